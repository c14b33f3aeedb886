"""The net layered over Blender's own Armature modifier, headless, on the
shared hand: the Armature modifier stays on, and a corrective shape key in
rest space (the rest position plus CurveLayer.rest_correction) makes the
evaluated mesh what curvenet's layer computes, for linear blend skinning
and for Preserve Volume (dual quaternions); with the key at 0 it is the
Armature modifier's own skin; saving and reloading keeps the layer.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

import addon_support as t  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Quaternion, Vector  # noqa: E402

t.empty_scene()
t.enable_addon()
import curvenet  # noqa: E402
from curvenet_blender import core  # noqa: E402

HAND = os.path.join(t.DATA, "xr_tools_hand")
meshes, arms = t.import_gltf(os.path.join(HAND, "hand_l.gltf"))
obj, arm = meshes[0], arms[0]
mod = core.armature_modifier(obj, arm)
t.check(mod is not None, "the import comes with its Armature modifier")
core.starter(obj, arm)
diag = core.state(obj).diagonal


def pose(angle):
    for name in ("Index_Proximal_L", "Index_Intermediate_L", "Middle_Proximal_L", "Thumb_Proximal_L"):
        pb = arm.pose.bones[name]
        pb.rotation_mode = "QUATERNION"
        pb.rotation_quaternion = Quaternion((1, 0, 0), angle)
    bpy.context.view_layer.update()


def layered_error(obj, arm):
    st = core.state(obj)
    core.update_live(obj, force=True)
    want = st.layer.deform(core.skinning_matrices(obj, arm))
    return np.abs(t.evaluated_positions(obj) - want).max() / diag


for preserve in (False, True):
    mod.use_deform_preserve_volume = preserve
    if preserve:
        core.bind(obj, arm, layer=True)
    else:  # through the panel's checkbox and the Bind button
        bpy.context.scene.curvenet.layer = True
        t.select(obj, arm)
        t.check(bpy.ops.curvenet.bind() == {"FINISHED"}, "Bind: " + bpy.context.scene.curvenet.status)
        t.check("over the Armature" in bpy.context.scene.curvenet.status, bpy.context.scene.curvenet.status)
    st = core.state(obj)
    t.check(st.layer is not None and st.layer.over_skin, "bound as a layer over the skin")
    t.check(mod.show_viewport and mod.show_render, "the Armature modifier stays on")
    pose(0.9)
    err = layered_error(obj, arm)
    t.check(err < 1e-5, "preserve volume %s: the evaluated mesh is the layer (max %.2e of the diagonal)" % (preserve, err))
    # The correction is real, and with the key at 0 the mesh is the Armature modifier's own.
    key = obj.data.shape_keys.key_blocks[core.SHAPE_KEY]
    layered = t.evaluated_positions(obj)
    key.value = 0.0
    skin = t.evaluated_positions(obj)
    key.value = 1.0
    moved = np.abs(layered - skin).max() / diag
    t.check(moved > 1e-3, "the layer corrects the skin (by up to %.2f%% of the diagonal)" % (100 * moved))
    want_skin = st.layer.deform(core.skinning_matrices(obj, arm), envelope=0.0)
    skin_err = np.abs(skin - want_skin).max() / diag
    t.check(skin_err < 1e-5, "the key at 0 is curvenet's skin of the vertex groups (max %.2e)" % skin_err)
    pose(0.0)

# A node pulled by a handle keyed on the timeline: at rest at frames 1 and
# 20, pulled by 2 % of the diagonal at frame 10.
scene = bpy.context.scene
scene.frame_set(1)
pose(0.6)
st = core.state(obj)
rig = core.get_rig(obj)
node = next(n.id for n in rig.nodes if core._heaviest_bone(obj, n.id) == "Index_Intermediate_L")
# Through the panel: Pick gives the selection, Pull adds its handle (once).
bpy.context.scene.curvenet.selected_nodes = node
t.select(obj)
t.check(bpy.ops.curvenet.pull_node() == {"FINISHED"}, "Pull: " + bpy.context.scene.curvenet.status)
t.check(len(core.node_handles(obj)) == 1, "Pull adds one handle")
handle = core.node_handles(obj)[0]
t.check(handle[core.HANDLE_KEY] == node and node in bpy.context.scene.curvenet.status, "for the picked node")
t.check(bpy.ops.curvenet.pull_node() == {"FINISHED"} and len(core.node_handles(obj)) == 1,
        "pulling a node that has a handle keeps its one handle")
t.check(core.add_node_handle(obj, node) == handle, "and gives it back")
bpy.context.scene.curvenet.selected_nodes = "no_such_node"
try:
    refused = bpy.ops.curvenet.pull_node() == {"CANCELLED"}
except RuntimeError:  # headless, an operator's error report raises
    refused = True
t.check(refused and len(core.node_handles(obj)) == 1, "a node the net lacks is refused")
t.check("no node no_such_node" in bpy.context.scene.curvenet.status, bpy.context.scene.curvenet.status)
t.check(handle.parent_bone == "Index_Intermediate_L", "the handle rides on the node's bone")
t.check(abs(sum(core.node_weights(obj, node).values()) - 1) < 1e-9, "the node's weights, from the binding, sum to 1")
for f in (1, 20):
    handle.keyframe_insert("location", frame=f)
rest_location = handle.location.copy()
handle.location = rest_location + Vector((0.02 * diag, 0, 0))
handle.keyframe_insert("location", frame=10)


def pulled_by(frame):
    scene.frame_set(frame)
    core.update_live(obj, force=True)
    plain = st.layer.deform(core.skinning_matrices(obj, arm))
    return np.abs(t.evaluated_positions(obj) - plain).max() / diag


for f in (1, 20):
    t.check(pulled_by(f) < 1e-5, "frame %d, keyed at rest: the mesh is the layer unpulled" % f)
at10 = pulled_by(10)
t.check(at10 > 5e-3, "frame 10: the pulled node moves the mesh (by %.2f%% of the diagonal)" % (100 * at10))
t.check(len(core.node_offsets(obj)) == 1, "one node pulled at frame 10")
scene.frame_set(1)

# Saved and reloaded, the layer binds again as a layer.
path = os.path.join(t.OUT, "layer.blend")
names = obj.name, arm.name
core.forget(obj)
bpy.ops.wm.save_as_mainfile(filepath=path)
bpy.ops.wm.open_mainfile(filepath=path)
obj, arm = bpy.data.objects[names[0]], bpy.data.objects[names[1]]
t.check(core.ensure_binding(obj) is not None, "the reloaded object binds again")
t.check(core.state(obj).layer is not None, "as a layer")
pose(0.6)
err = layered_error(obj, arm)
t.check(err < 1e-5, "after reloading, the evaluated mesh is the layer (max %.2e)" % err)
scene = bpy.context.scene
scene.frame_set(10)
core.update_live(obj, force=True)
st = core.state(obj)
plain = st.layer.deform(core.skinning_matrices(obj, arm))
kept = np.abs(t.evaluated_positions(obj) - plain).max() / diag
t.check(kept > 5e-3, "after reloading, the handle's key still pulls the node at frame 10 (%.2f%%)" % (100 * kept))

# The envelope and the mask are the shape key's value and vertex group: the
# panel shows them while the mesh is layered, and Blender scales the
# correction by both before the Armature modifier moves it.
key = core.layer_key(obj)
t.check(key is not None and key.value == 1.0, "a layered mesh has the envelope at 1")
group = obj.vertex_groups.new(name="curvenet_mask")
n = len(obj.data.vertices)
inside = [i for i in range(n) if obj.data.vertices[i].co.x > np.median([v.co.x for v in obj.data.vertices])]
group.add(inside, 0.5, "REPLACE")
key.vertex_group = group.name
weights = core.group_weights(obj, group.name)
t.check(np.count_nonzero(weights) == len(inside) and weights.max() == 0.5, "the mask's weights, per vertex")
scene.frame_set(10)
core.update_live(obj, force=True)
M = core.skinning_matrices(obj, arm)
got = t.evaluated_positions(obj)
skin_only = st.layer.deform(M, envelope=0.0, offsets=core.node_offsets(obj))
masked = st.layer.with_mask(weights).deform(M, offsets=core.node_offsets(obj))
outside = weights == 0
err_out = np.abs(got[outside] - skin_only[outside]).max() / diag
err_in = np.abs(got - masked).max() / diag
t.check(err_out < 1e-5, "masked out, the mesh is the skin (max %.2e of the diagonal)" % err_out)
t.check(err_in < 1e-5, "masked at 0.5, the mesh is the layer with that mask (max %.2e)" % err_in)
t.check(np.abs(masked - skin_only)[~outside].max() > 1e-4 * diag, "inside the mask the layer still corrects")
# Keyed: the envelope 0 at frame 1 and 1 at frame 10; then the bake holds
# what played, frame by frame (the envelope, the mask and the pulled node).
key.value = 0.0
key.keyframe_insert("value", frame=1)
key.value = 1.0
key.keyframe_insert("value", frame=10)
cache = os.path.join(t.OUT, "layer_bake.pc2")
played = []
for f in range(1, 11):
    scene.frame_set(f)
    core.update_live(obj, force=True)
    played.append(t.evaluated_positions(obj))
t.check(abs(key.value - 1.0) < 1e-9, "the keyed envelope plays (1 at frame 10)")
scene.frame_set(1)
t.check(np.abs(t.evaluated_positions(obj) - st.layer.deform(core.skinning_matrices(obj, arm), envelope=0.0)).max()
        < 1e-5 * diag, "the envelope keyed at 0 on frame 1: the skin")
core.bake_cache(obj, cache, 1, 10)
with open(cache, "rb") as f:
    head = f.read(32)
    baked = np.frombuffer(f.read(), dtype="<f4").reshape(10, n, 3).astype(np.float64)
worst = max(np.abs(baked[k] - played[k]).max() for k in range(10)) / diag
t.check(worst < 1e-5, "the bake of a layer is what played, frame by frame (max %.2e of the diagonal)" % worst)
t.check(np.abs(played[4] - played[0]).max() > 1e-3 * diag, "and what played changed over the frames")
print("CURVENET_TEST all passed")
