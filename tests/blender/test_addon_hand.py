"""The add-on's whole workflow on the shared hand (hand_l.gltf with its
armature), headless, through the non-modal core and the operators:

1. draw a small net with the non-modal core (a ring round the index finger);
2. connect, and check the counts;
3. make a starter net from the armature, connect, and bind;
4. set one node weight, rotate a bone, and check that the evaluated mesh equals
   curvenet.Binding.deform for the same matrices, posing and scrubbing;
5. transfer to Hand_low_L.gltf;
6. render Workbench PNGs of the region preview and a posed frame;
and bake a cache that plays without the add-on.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

import addon_support as t  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Quaternion, Vector  # noqa: E402

t.empty_scene()  # factory settings first: they switch add-ons off
t.enable_addon()
import curvenet  # noqa: E402
import curvenet_blender  # noqa: E402
from curvenet_blender import core, draw  # noqa: E402

HAND = os.path.join(t.DATA, "xr_tools_hand")
meshes, arms = t.import_gltf(os.path.join(HAND, "hand_l.gltf"))
obj, arm = meshes[0], arms[0]
rest = np.array([v.co[:] for v in obj.data.vertices])
t.check(len(obj.modifiers) and obj.modifiers[0].type == "ARMATURE", "the import comes with its own skin")

# --- 1. draw a ring round the index finger with the non-modal core ---------
bone = arm.data.bones["Index_Intermediate_L"]
W = arm.matrix_world
head, tail = W @ bone.head_local, W @ bone.tail_local
centre = (head + tail) / 2
axis = (tail - head).normalized()
u = axis.orthogonal().normalized()
v = axis.cross(u)
rays = [(u * np.cos(a) + v * np.sin(a)).normalized() for a in np.radians([0, 90, 180, 270])]
nodes = []
for d in rays:
    nodes.append(core.add_node_at(obj, centre, d))  # from inside the finger, out to its surface
t.check(len(set(nodes)) == 4 and None not in nodes, "four rays place four nodes")
for n, d in zip(nodes, rays):
    hit = core.surface_hit(obj, centre, d)
    t.check(np.allclose(core.get_rig(obj).node(n).position, hit), "node %s is where its ray meets the surface" % n)
# A click near a node reuses it (tolerance scaled to the mesh).
again = core.add_node_at(obj, centre, (rays[0] + 0.02 * rays[1]).normalized())
t.check(again == nodes[0], "a click near node %s reuses it" % nodes[0])
t.check(core.add_node_at(obj, centre + axis * 10, axis) is None, "a ray that misses the mesh places nothing")
pids = [core.add_profile(obj, nodes[i], nodes[(i + 1) % 4]) for i in range(4)]
rig = core.get_rig(obj)
t.check(len(rig.nodes) == 4 and len(rig.profiles) == 4, "the ring has 4 nodes and 4 profiles")
# The overlay draws the traced path of each profile: the path the cut follows.
geo = draw.overlay_geometry(obj, bpy.context.scene)
t.check(len(geo["path"]) > 0 and len(geo["node"]) == 4, "the overlay has paths and node markers")
# Ctrl+Z removes the last profile; drawing it again restores the ring.
removed = core.remove_last_profile(obj)
t.check(removed == pids[-1] and len(core.get_rig(obj).profiles) == 3, "undo removes the last profile")
t.check(len(core.get_rig(obj).nodes) == 4, "the nodes the other profiles use stay")
core.add_profile(obj, nodes[3], nodes[0])
t.check("curvenet_rig" in obj and obj["curvenet_rig"].startswith("{"), "the rig lives on the object")

# The modal Draw operator is a shell over the same core: fed events (the ray
# under the mouse given with each), it draws the same ring.
from types import SimpleNamespace  # noqa: E402

from curvenet_blender import operators  # noqa: E402

drawn_by_core = core.get_rig(obj).to_json()
core.clear_rig(obj)
obj_name, arm_name = obj.name, arm.name
bpy.ops.ed.undo_push(message="before drawing")
shell = t.draw_shell(obj_name)


def event(kind, ray=None, ctrl=False):
    return SimpleNamespace(type=kind, value="PRESS", ctrl=ctrl, shift=False, ray=ray)


def step(e):
    return operators.CURVENET_OT_draw._step(shell, bpy.context, e)


clicks = rays + [rays[0]]
for i, d in enumerate(clicks):
    if i > 0:  # the mouse passes over the arc between the last click and this one
        for s in (0.3, 0.5, 0.7):
            step(event("MOUSEMOVE", (centre, ((1 - s) * clicks[i - 1] + s * d).normalized())))
    t.check(step(event("LEFTMOUSE", (centre, d))) == {"RUNNING_MODAL"}, "a click")
t.check(len(core.get_rig(obj).profiles) == 4, "five clicks round the finger make the ring's 4 profiles")
t.check(step(event("Z", ctrl=True)) == {"RUNNING_MODAL"}, "Ctrl+Z in Draw")
obj, arm = bpy.data.objects[obj_name], bpy.data.objects[arm_name]  # an undo replaces the objects
rig = core.get_rig(obj)
t.check(len(rig.profiles) == 3 and len(rig.nodes) == 4, "Ctrl+Z is Blender's undo: the last profile goes, and no node is left behind")
t.check(shell.previous == rig.profiles[2].to, "the stroke goes on from the last profile's end")
redo = SimpleNamespace(type="Z", value="PRESS", ctrl=True, shift=True, ray=None)
t.check(step(redo) == {"RUNNING_MODAL"}, "Ctrl+Shift+Z in Draw")
obj, arm = bpy.data.objects[obj_name], bpy.data.objects[arm_name]
t.check(len(core.get_rig(obj).profiles) == 4, "redo brings the profile back")
step(event("Z", ctrl=True))
obj, arm = bpy.data.objects[obj_name], bpy.data.objects[arm_name]
step(event("LEFTMOUSE", (centre, rays[0])))
t.check(step(event("RET")) == {"FINISHED"}, "Enter finishes")
rig = core.get_rig(obj)
t.check(len(rig.nodes) == 4 and len(rig.profiles) == 4, "the modal shell drew the same ring: 4 nodes, 4 profiles")
t.check(len(rig.profile("p1").curve.points) > 2, "a profile passes through the surface points the mouse went over")

# --- 2. connect ------------------------------------------------------------
t.select(obj)
result = bpy.ops.curvenet.connect()
st = core.state(obj)
report = core.connect_result(obj)["report"]
t.check(result == {"FINISHED"} and report["ok"], "Connect: " + bpy.context.scene.curvenet.status)
t.check(report["regions"] == 2 and report["expected_regions"] == 2, "a ring on a closed hand makes 2 regions")
t.check(bpy.context.scene.curvenet.status.startswith("SUCCESS"), "the panel says SUCCESS")
preview = bpy.data.objects[obj.name + core.PREVIEW_SUFFIX]
t.check(preview.data.color_attributes.get("regions") is not None, "the preview object has region colours")
t.check(np.array_equal(np.array([v.co[:] for v in obj.data.vertices]), rest), "the user's mesh is not edited")
# For every traced path, the chain the cut made ends at the same nodes.
for pid, chain in core.traced_paths(obj).items():
    t.check(len(chain) >= 2, "profile %s has a chain" % pid)

# A profile along the finger that crosses the ring between two of its nodes
# fails Connect with the engine's reason, and the profile it names is selected.
diag45 = (rays[0] + rays[1]).normalized()
length = (tail - head).length
e = core.add_node_at(obj, centre - axis * (0.35 * length), diag45)
f = core.add_node_at(obj, centre + axis * (0.35 * length), diag45)
across = core.add_profile(obj, e, f, [core.surface_hit(obj, centre, diag45)])
ok, _, message = core.connect(obj)
t.check(not ok and message.startswith("FAILED") and ("'%s'" % across) in message, "a crossing net fails: " + message)
failed = core.connect_result(obj)["failed_profile"]
t.check(failed == across, "the failure marks the profile drawn last of those it names (%s)" % failed)
t.select(obj)
t.check(bpy.ops.curvenet.connect() == {"CANCELLED"}, "the operator reports the failure")
t.check(bpy.context.scene.curvenet.selected_profile == across, "the named profile is selected")

# --- 3. starter net from the armature, connect, bind -----------------------
t.select(obj, arm)
t.check(bpy.ops.curvenet.starter() == {"FINISHED"}, "Starter: " + bpy.context.scene.curvenet.status)
rig = core.get_rig(obj)
t.check(len(rig.nodes) > 40 and rig.has_skeleton, "the starter net has %d nodes" % len(rig.nodes))
# The mesh's vertex groups (its skin) weight the nodes, as `curvenet starter` takes a file's skin.
joints = core.armature_joints(obj, arm)
deforming = core.deforming_bones(obj, arm)
from_groups = curvenet.starter(core.engine_mesh(obj), core.skin_from_groups(obj, joints), deforming=deforming)
by_rule = curvenet.starter(core.engine_mesh(obj), joints, deforming=deforming)
t.check(rig.to_json() == from_groups.rig.to_json(), "the starter's node weights come from the vertex groups")
t.check(rig.to_json() != by_rule.rig.to_json(), "and not from the bones' rule")
t.select(obj)
t.check(bpy.ops.curvenet.connect() == {"FINISHED"}, "the starter net connects: " + bpy.context.scene.curvenet.status)
t.select(obj, arm)
t.check(bpy.ops.curvenet.bind() == {"FINISHED"}, "Bind: " + bpy.context.scene.curvenet.status)
t.check(not obj.modifiers[0].show_viewport, "the file's own Armature modifier is off while bound")
t.check(np.abs(t.evaluated_positions(obj) - rest).max() < 1e-6, "at rest the mesh does not move")

# The panel draws for a bound mesh (its layout calls are recorded, not shown).
from unittest import mock  # noqa: E402

from curvenet_blender import ui  # noqa: E402

layout = mock.MagicMock()
ui.CURVENET_PT_panel.draw(SimpleNamespace(layout=layout), bpy.context)
drawn = str(layout.mock_calls)
t.check("curvenet.connect" in drawn and "curvenet.bind" in drawn and "curvenet.bake_cache" in drawn,
        "the panel shows the workflow's steps")
t.check("SUCCESS" in drawn, "the panel shows the last Connect's result")

# --- 4. a node weight, a bone rotated, the mesh equals Binding.deform -------
# The node of the starter net nearest the index finger's middle knuckle.
bone_name = "Index_Proximal_L"
knuckle = np.array(obj.matrix_world.inverted() @ arm.matrix_world @ arm.data.bones[bone_name].tail_local)
node = min(core.get_rig(obj).nodes, key=lambda n: np.linalg.norm(np.asarray(n.position) - knuckle)).id
t.select(obj, arm)
arm.data.bones.active = arm.data.bones[bone_name]
t.check(bpy.ops.curvenet.set_node_weight(nodes=node, weight=0.75) == {"FINISHED"}, "Set node weight")
w = dict(core.get_rig(obj).weights[node])
t.check(abs(w[bone_name] - 0.75) < 1e-12 and abs(sum(w.values()) - 1) < 1e-12, "the node's weights: %s" % w)
t.check(abs(core.state(obj).binding.node_weights[node][bone_name] - 0.75) < 1e-12, "the binding uses the new weight")


def expected_matrices():
    """Skinning matrices computed here from the armature, independently of the add-on."""
    binding = core.state(obj).binding
    O, A = obj.matrix_world, arm.matrix_world
    M = []
    for name in binding.joint_names:
        pb = arm.pose.bones[name]
        M.append(np.array(O.inverted() @ A @ pb.matrix @ pb.bone.matrix_local.inverted() @ A.inverted() @ O))
    return np.array(M)


def check_pose(label):
    bpy.context.view_layer.update()  # the handler writes the deformed positions
    bpy.context.view_layer.update()  # and the depsgraph evaluates them
    got = t.evaluated_positions(obj)
    want = core.state(obj).binding.deform(expected_matrices())
    err = np.abs(got - want).max()
    scale = np.abs(want).max()
    t.check(err <= 4e-7 * scale, "%s: the evaluated mesh equals Binding.deform (max error %.3g)" % (label, err))
    return got


pb = arm.pose.bones[bone_name]
pb.rotation_mode = "QUATERNION"
pb.rotation_quaternion = Quaternion((1, 0, 0), np.radians(60))
posed = check_pose("posing")
t.check(np.abs(posed - rest).max() > 0.005, "the bone's rotation moves the mesh")
# Scrubbing: keys at frames 1 and 21, evaluated at frame 11.
scene = bpy.context.scene
pb.rotation_quaternion = Quaternion((1, 0, 0), 0)
pb.keyframe_insert("rotation_quaternion", frame=1)
pb.rotation_quaternion = Quaternion((1, 0, 0), np.radians(80))
pb.keyframe_insert("rotation_quaternion", frame=21)
scene.frame_start, scene.frame_end = 1, 21
scene.frame_set(11)
check_pose("scrubbing to frame 11")
scene.frame_set(21)
check_pose("scrubbing to frame 21")

# The gradient mode, through the same operator: the evaluated mesh is its deformation.
t.select(obj, arm)
t.check(bpy.ops.curvenet.bind(method="gradient") == {"FINISHED"}, "Bind (gradient): " + scene.curvenet.status)
t.check(core.state(obj).binding.method == "gradient", "the binding is in the gradient mode")
check_pose("the gradient mode at frame 21")
t.check(bpy.ops.curvenet.bind(method="harmonic") == {"FINISHED"}, "and back to the harmonic mode")

# --- 6. renders: a posed frame, and the region preview ---------------------
t.render_workbench([obj], os.path.join(t.OUT, "hand_posed.png"), colour="SINGLE")
t.select(obj)
bpy.ops.curvenet.connect()
preview = bpy.data.objects[obj.name + core.PREVIEW_SUFFIX]
chains = bpy.data.objects[obj.name + core.CHAINS_SUFFIX]
t.check(preview.hide_viewport and chains.hide_viewport, "while the mesh is posed (frame 21), the rest-pose preview hides")
scene.frame_set(1)
t.check(not preview.hide_viewport and not chains.hide_viewport, "at the rest frame the preview shows, bound or not")
t.check(bpy.ops.curvenet.unbind() == {"FINISHED"} and not preview.hide_viewport, "unbound at rest, the preview shows")
scene.frame_set(21)
t.check(preview.hide_viewport, "posed by the mesh's own skin, the preview hides too")
scene.frame_set(1)
t.check(len(preview.data.materials) > 1 and preview.hide_select,
        "the regions show in Solid shading (one material per colour); a click selects the mesh, not its preview")
obj.hide_render = True
t.render_workbench([preview, chains], os.path.join(t.OUT, "hand_regions.png"), colour="VERTEX")
t.render_workbench([preview, chains], os.path.join(t.OUT, "hand_regions_material.png"), colour="MATERIAL")
obj.hide_render = False
t.select(obj, arm)
t.check(bpy.ops.curvenet.bind() == {"FINISHED"}, "bound again")

# --- bake a cache that plays without the add-on ----------------------------
pc2 = os.path.join(t.OUT, "hand_bake.pc2")
scene.frame_set(11)
live_11 = t.evaluated_positions(obj)
t.select(obj, arm)
t.check(bpy.ops.curvenet.bake_cache(filepath=pc2) == {"FINISHED"}, "Bake cache: " + scene.curvenet.status)
t.check(obj.modifiers[0].type == "MESH_CACHE", "the Mesh Cache modifier comes first")
curvenet_blender.unregister()  # the cache plays with the add-on off
scene.frame_set(1)
scene.frame_set(11)
baked_11 = t.evaluated_positions(obj)
err = np.abs(baked_11 - live_11).max()
t.check(err < 1e-6, "the baked cache plays frame 11 as the live deformation showed it (max error %.3g)" % err)
curvenet_blender.register()

# --- 5. transfer to the low-resolution hand --------------------------------
low_meshes, low_arms = t.import_gltf(os.path.join(HAND, "Hand_low_L.gltf"))
low = low_meshes[0]
t.select(obj, low)
t.check(bpy.ops.curvenet.transfer() == {"FINISHED"}, scene.curvenet.status)
low_rig = core.get_rig(low)
t.check(len(low_rig.nodes) == len(core.get_rig(obj).nodes), "the transferred rig has the same nodes")
t.check("agrees" in scene.curvenet.status, "the panel shows the agreement: " + scene.curvenet.status)
agreement = float(scene.curvenet.status.split("%")[0].split()[-1])
t.check(agreement > 99.0, "the regions agree over %.2f%% of the area" % agreement)
t.select(low)
t.check(bpy.ops.curvenet.connect() == {"FINISHED"}, "the transferred rig connects on the low hand")

# Export and import round trip.
path = os.path.join(t.OUT, "hand_from_blender.cnrig.json")
t.select(obj)
t.check(bpy.ops.curvenet.export_rig(filepath=path) == {"FINISHED"}, "Export rig")
t.check(curvenet.read_rig(path).to_json() == core.get_rig(obj).to_json(), "the exported rig reads back the same")
t.select(low)
t.check(bpy.ops.curvenet.import_rig(filepath=path) == {"FINISHED"}, "Import rig")
# The rig is saved in the .blend, and a bound mesh deforms again after loading.
t.select(low, low_arms[0])
t.check(bpy.ops.curvenet.bind() == {"FINISHED"}, "the low hand binds to its armature")
blend = os.path.join(t.OUT, "hand_low_bound.blend")
bpy.ops.wm.save_as_mainfile(filepath=blend)
saved_rig, low_name = low["curvenet_rig"], low.name
bpy.ops.wm.open_mainfile(filepath=blend)
low = bpy.data.objects[low_name]
low_arm = core.bound_armature(low)
t.check(low["curvenet_rig"] == saved_rig, "the rig comes back with the .blend")
t.check(low_arm is not None and core.state(low).binding is not None, "after loading, the mesh is bound again")
pb = low_arm.pose.bones["Middle_Proximal_L"]
pb.rotation_mode = "QUATERNION"
pb.rotation_quaternion = Quaternion((1, 0, 0), np.radians(50))
bpy.context.view_layer.update()
bpy.context.view_layer.update()
low_rest = np.array([v.co[:] for v in low.data.vertices])
moved = np.abs(t.evaluated_positions(low) - low_rest).max()
t.check(core.state(low).binding is not None and moved > 0.002, "the loaded mesh follows its armature (moved %.4f)" % moved)
print("CURVENET_TEST all passed")
