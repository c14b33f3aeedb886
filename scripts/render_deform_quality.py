"""Renders a row of PLY meshes side by side (Workbench, vertex colours),
each labelled with its file name: the pictures of docs/deform.md's
comparison with the skins (bench/deform_quality --ply DIR CASE).

    blender -b --factory-startup --python-exit-code 1 \
        --python scripts/render_deform_quality.py -- OUT.png DIR NAME... [--view X Y Z] [--up X Y Z]
"""

import math
import os
import sys

import bpy
from mathutils import Matrix, Vector

argv = sys.argv[sys.argv.index("--") + 1:]
view = up = None
if "--view" in argv:
    i = argv.index("--view")
    view = Vector([float(x) for x in argv[i + 1:i + 4]])
    del argv[i:i + 4]
if "--up" in argv:
    i = argv.index("--up")
    up = Vector([float(x) for x in argv[i + 1:i + 4]])
    del argv[i:i + 4]
out, folder, names = argv[0], argv[1], argv[2:]

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
view = (view or Vector((0, 0, 1))).normalized()
up = up or Vector((0, 1, 0))
y = (up - view * up.dot(view)).normalized()
x = y.cross(view)
objects = []
offset = 0.0
for name in names:
    before = set(bpy.data.objects)
    bpy.ops.import_mesh.ply(filepath=os.path.join(folder, name + ".ply"))
    obj = [o for o in bpy.data.objects if o not in before][0]
    # PLY import turns Y-up files Z-up: undo it so that --view speaks the file's axes.
    obj.rotation_euler = (0, 0, 0)
    bpy.context.view_layer.update()
    pts = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    lo = min(p.dot(x) for p in pts)
    hi = max(p.dot(x) for p in pts)
    obj.location = x * (offset - lo)
    bottom = min(p.dot(y) for p in pts)
    offset += (hi - lo) * 1.15
    text = bpy.data.curves.new(name + "_label", "FONT")
    text.body = name
    text.align_x = "CENTER"
    label = bpy.data.objects.new(name + "_label", text)
    scene.collection.objects.link(label)
    label.matrix_world = Matrix.Translation(x * (offset - (hi - lo) * 0.65) + y * (bottom - 0.12 * (hi - lo)) ) @ Matrix(
        [[x[0], y[0], view[0], 0], [x[1], y[1], view[1], 0], [x[2], y[2], view[2], 0], [0, 0, 0, 1]])
    label.scale = [0.18 * (hi - lo)] * 3
    objects.append(obj)
    objects.append(label)

scene.render.engine = "BLENDER_WORKBENCH"
scene.render.resolution_x, scene.render.resolution_y = 400 * len(names), 520
scene.render.image_settings.file_format = "PNG"
scene.world = bpy.data.worlds.new("w")
scene.world.color = (0.82, 0.84, 0.87)
shading = scene.display.shading
shading.light = "STUDIO"
shading.color_type = "VERTEX"
scene.display.render_aa = "8"
bpy.context.view_layer.update()
pts = [o.matrix_world @ Vector(c) for o in objects for c in o.bound_box]
lo = Vector([min(p[k] for p in pts) for k in range(3)])
hi = Vector([max(p[k] for p in pts) for k in range(3)])
centre = (lo + hi) / 2
cam_data = bpy.data.cameras.new("cam")
cam_data.type = "ORTHO"
width = max(p.dot(x) for p in pts) - min(p.dot(x) for p in pts)
height = max(p.dot(y) for p in pts) - min(p.dot(y) for p in pts)
cam_data.ortho_scale = 1.05 * max(width, height * scene.render.resolution_x / scene.render.resolution_y)
cam = bpy.data.objects.new("cam", cam_data)
scene.collection.objects.link(cam)
distance = (hi - lo).length * 2
cam.matrix_world = Matrix.Translation(centre + view * distance) @ Matrix(
    [[x[0], y[0], view[0], 0], [x[1], y[1], view[1], 0], [x[2], y[2], view[2], 0], [0, 0, 0, 1]])
cam_data.clip_start = distance / 100
cam_data.clip_end = distance * 10
scene.camera = cam
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
