"""Renders the pictures of README.md and docs/blender.md with the add-on,
headless (Workbench), from the shared data:

    scripts/pictures.sh        (builds, then runs this in Blender)

1. blender_drawn_ring.png: a ring drawn round the index finger with the
   non-modal core, connected: two regions.
2. blender_regions.png: the starter net made from the hand's armature, connected.
3. blender_grip.png: the hand bound through that net, posed by the file's Grip clip.
4. blender_cesium_walk.png: a 700-triangle CesiumMan variant, started, bound and walking.
5. bake_glb_in_blender.png: the hand baked to an ordinary skin (`curvenet bake`,
   here through the module), opened by Blender's own glTF importer, posed by
   its armature in the Grip clip.
6. deform_fist_harmonic.png, deform_fist_gradient.png: the example rig's fist
   in the harmonic and the gradient mode (docs/deform.md).
"""

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "blender"))

import addon_support as t  # noqa: E402  (reads BUILD DATA OUT after "--")
import bpy  # noqa: E402
import numpy as np  # noqa: E402

t.empty_scene()
t.enable_addon()
from curvenet_blender import core  # noqa: E402

HAND = os.path.join(t.DATA, "xr_tools_hand")


def hand_scene():
    t.empty_scene()
    t.enable_addon()
    meshes, arms = t.import_gltf(os.path.join(HAND, "hand_l_poses.glb"))
    return meshes[0], arms[0]


def preview_objects(obj):
    return [bpy.data.objects[obj.name + core.PREVIEW_SUFFIX], bpy.data.objects[obj.name + core.CHAINS_SUFFIX]]


# 1. A ring drawn with the non-modal core.
obj, arm = hand_scene()
arm.animation_data.action = None
for pb in arm.pose.bones:
    pb.matrix_basis.identity()
bone = arm.data.bones["Index_Intermediate_L"]
W = arm.matrix_world
head, tail = W @ bone.head_local, W @ bone.tail_local
centre, axis = (head + tail) / 2, (tail - head).normalized()
u = axis.orthogonal().normalized()
v = axis.cross(u)
nodes = [core.add_node_at(obj, centre, (u * np.cos(a) + v * np.sin(a)).normalized()) for a in np.radians([0, 90, 180, 270])]
for i in range(4):
    core.add_profile(obj, nodes[i], nodes[(i + 1) % 4])
ok, _, message = core.connect(obj)
print("drawn ring:", message)
obj.hide_render = True
t.render_workbench(preview_objects(obj), os.path.join(t.OUT, "blender_drawn_ring.png"), colour="VERTEX", size=(640, 480))

# 2. and 3. The starter net, and the Grip pose through it.
obj, arm = hand_scene()
action = arm.animation_data.action
arm.animation_data.action = None
for pb in arm.pose.bones:
    pb.matrix_basis.identity()
bpy.context.view_layer.update()
result = core.starter(obj, arm)
ok, _, message = core.connect(obj)
print("starter:", message)
obj.hide_render = True
t.render_workbench(preview_objects(obj), os.path.join(t.OUT, "blender_regions.png"), colour="VERTEX", size=(640, 480))
for o in preview_objects(obj):
    o.hide_render = True
obj.hide_render = False
core.bind(obj, arm)
arm.animation_data.action = bpy.data.actions["Grip_Armature"]
bpy.context.scene.frame_set(2)
bpy.context.view_layer.update()
core.update_live(obj, bpy.context.evaluated_depsgraph_get())
bpy.context.view_layer.update()
t.render_workbench([obj], os.path.join(t.OUT, "blender_grip.png"), colour="SINGLE", size=(640, 480))

# 4. A low-poly CesiumMan variant walking.
t.empty_scene()
t.enable_addon()
cesium = os.path.join(t.DATA, "cesium_man")
meshes, arms = t.import_gltf(os.path.join(cesium, "CesiumMan.glb"))
skin, arm = meshes[0], arms[0]
before = set(bpy.data.objects)
bpy.ops.wm.obj_import(filepath=os.path.join(cesium, "variants", "cesium_man_c_decimated.obj"))
variant = [o for o in bpy.data.objects if o not in before][0]
variant.matrix_world = skin.matrix_world @ variant.matrix_world
skin.hide_render = True
bpy.context.view_layer.update()
core.starter(variant, arm)
print("cesium:", core.connect(variant)[2])
for o in preview_objects(variant):
    o.hide_render = True
core.bind(variant, arm)
bpy.context.scene.frame_set(12)
bpy.context.view_layer.update()
t.render_workbench([variant], os.path.join(t.OUT, "blender_cesium_walk.png"), colour="SINGLE", size=(480, 640),
                   view=(0.5, -1.0, 0.25), up=(0, 0, 1))
# 5. The baked skin, in a viewer that knows nothing of curvenet.
import tempfile  # noqa: E402

import curvenet  # noqa: E402

t.empty_scene()
source = os.path.join(HAND, "hand_l.gltf")
binding = curvenet.bind(curvenet.load_mesh(source), curvenet.read_rig(os.path.join(HAND, "example", "hand_l.cnrig.json")))
clips = curvenet.load_skinned_mesh(os.path.join(HAND, "hand_l_poses.glb"))
glb = os.path.join(tempfile.mkdtemp(), "hand_baked.glb")
curvenet.write_file(glb, curvenet.skinned_glb(source, binding, curvenet.bake_weights(binding, 4), clips,
                                              clip_names=["Grip"]))
meshes, arms = t.import_gltf(glb)
bpy.context.scene.frame_set(1)
t.render_workbench(meshes, os.path.join(t.OUT, "bake_glb_in_blender.png"), colour="SINGLE", size=(640, 480))
# 6. The example fist, in both modes.
example = os.path.join(HAND, "example")
mesh = curvenet.load_mesh(os.path.join(example, "hand_l_welded.obj"))
rig = curvenet.read_rig(os.path.join(example, "hand_l.cnrig.json"))
for method in ("harmonic", "gradient"):
    t.empty_scene()
    bpy.ops.wm.obj_import(filepath=os.path.join(example, "hand_l_welded.obj"))
    obj = bpy.context.selected_objects[0]
    b = curvenet.bind(mesh, rig, method=method)
    P = b.deform(curvenet.skinning_matrices(b, os.path.join(example, "fist.pose.json")))
    obj.data.vertices.foreach_set("co", P.astype(np.float32).ravel())  # the OBJ importer keeps the file's order
    obj.data.polygons.foreach_set("use_smooth", [True] * len(obj.data.polygons))
    obj.data.update()
    t.render_workbench([obj], os.path.join(t.OUT, "deform_fist_%s.png" % method), colour="SINGLE", size=(480, 360))
print("pictures in", t.OUT)
