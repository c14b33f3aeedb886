"""The demo's Blender step: the add-on on the tube from `curvenet demo`,
headless. It imports the mesh and its rig, makes an armature from the rig's
skeleton, connects, binds, keys a bend, bakes a PC2 cache, saves
tube.blend (which plays without the add-on) and renders tube_blender.png.

    blender -b --factory-startup --python-exit-code 1 --python scripts/demo_blender.py -- build out/demo
"""

import os
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1 :]
build, out = (os.path.abspath(a) for a in args[:2])
bpy.ops.wm.read_factory_settings(use_empty=True)
sys.path.insert(0, os.path.join(build, "blender"))
import addon_utils  # noqa: E402

addon_utils.enable("curvenet_blender", default_set=True, handle_error=None)

bpy.ops.wm.obj_import(filepath=os.path.join(out, "tube_quads.obj"))
tube = bpy.context.selected_objects[0]
bpy.context.view_layer.objects.active = tube
ops = bpy.ops.curvenet
assert ops.import_rig(filepath=os.path.join(out, "tube.cnrig.json")) == {"FINISHED"}
assert ops.make_armature() == {"FINISHED"}
arm = bpy.context.scene.curvenet.armature
assert ops.connect() == {"FINISHED"}, bpy.context.scene.curvenet.status
print("blender: " + bpy.context.scene.curvenet.status)
tube.select_set(True)
arm.select_set(True)
assert ops.bind() == {"FINISHED"}, bpy.context.scene.curvenet.status
print("blender: " + bpy.context.scene.curvenet.status)
mid = arm.pose.bones["mid"]
mid.rotation_mode = "XYZ"
for frame, angle in ((1, 0.0), (24, 1.5708)):
    mid.rotation_euler = (angle, 0.0, 0.0)
    mid.keyframe_insert("rotation_euler", frame=frame)
scene = bpy.context.scene
scene.frame_start, scene.frame_end = 1, 24
assert ops.bake_cache(filepath=os.path.join(out, "tube_blender.pc2")) == {"FINISHED"}
print("blender: " + scene.curvenet.status)
for o in list(scene.objects):
    if o.name.endswith((".curvenet_regions", ".curvenet_chains")):
        o.hide_render = True
scene.frame_set(24)
scene.render.engine = "BLENDER_WORKBENCH"
scene.render.resolution_x, scene.render.resolution_y = 480, 480
# A camera that frames the tube's world bounding box, from the side of the bend.
from mathutils import Vector  # noqa: E402

bpy.context.view_layer.update()
corners = [tube.matrix_world @ Vector(c) for c in tube.bound_box]
centre = sum(corners, Vector()) / 8
size = max((c - centre).length for c in corners)
cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
scene.collection.objects.link(cam)
direction = Vector((1.0, -0.6, 0.4)).normalized()
cam.location = centre + direction * size * 4.0
cam.rotation_euler = (-direction).to_track_quat("-Z", "Z").to_euler()
scene.camera = cam
scene.render.filepath = os.path.join(out, "tube_blender.png")
bpy.ops.render.render(write_still=True)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "tube.blend"))
print("blender: tube.blend (plays its Mesh Cache without the add-on), tube_blender.png")
