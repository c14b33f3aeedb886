"""Renders PLY meshes side by side (Workbench, vertex colours), one panel
each, labelled with the file name: the pictures of docs/deform.md's
comparison with the skins (bench/deform_quality --ply DIR CASE).

    blender -b --factory-startup --python-exit-code 1 --python scripts/render_deform_quality.py -- \\
        OUT.png DIR NAME[:LABEL]... [--view X Y Z] [--up X Y Z] [--focus X Y Z R] [--panel W H]

--view is the direction towards the camera and --up the picture's up, in
the file's axes; --focus frames a ball of radius R about a point (default:
each mesh's bounding box).
"""

import os
import sys

import bpy
import numpy as np
from mathutils import Matrix, Vector


def take(argv, flag, count):
    if flag not in argv:
        return None
    i = argv.index(flag)
    values = [float(x) for x in argv[i + 1:i + 1 + count]]
    del argv[i:i + 1 + count]
    return values


argv = sys.argv[sys.argv.index("--") + 1:]
view = Vector(take(argv, "--view", 3) or (0, 0, 1)).normalized()
up = Vector(take(argv, "--up", 3) or (0, 1, 0))
focus = take(argv, "--focus", 4)
panel = [int(v) for v in (take(argv, "--panel", 2) or (420, 520))]
out, folder, names = argv[0], argv[1], argv[2:]

y_axis = (up - view * up.dot(view)).normalized()
x_axis = y_axis.cross(view)
basis = Matrix([[x_axis[k], y_axis[k], view[k], 0] for k in range(3)] + [[0, 0, 0, 1]])

tiles = []
for entry in names:
    name, _, label_text = entry.partition(":")
    label_text = label_text or name
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_mesh.ply(filepath=os.path.join(folder, name + ".ply"))
    obj = bpy.context.selected_objects[0]
    obj.rotation_euler = (0, 0, 0)  # the file's own axes, so that --view speaks them
    bpy.context.view_layer.update()
    pts = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    if focus:
        centre, radius = Vector(focus[:3]), focus[3]
    else:
        lo = Vector([min(p[k] for p in pts) for k in range(3)])
        hi = Vector([max(p[k] for p in pts) for k in range(3)])
        centre, radius = (lo + hi) / 2, (hi - lo).length / 2
    cam_data = bpy.data.cameras.new("cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.1 * radius * max(1.0, panel[0] / panel[1])
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    cam.matrix_world = Matrix.Translation(centre + view * radius * 4) @ basis
    cam_data.clip_start = radius / 100
    cam_data.clip_end = radius * 20
    scene.camera = cam
    text = bpy.data.curves.new("label", "FONT")
    text.body = label_text
    text.align_x = "CENTER"
    label = bpy.data.objects.new("label", text)
    scene.collection.objects.link(label)
    label.matrix_world = Matrix.Translation(centre - y_axis * radius * 0.92 + view * radius * 2) @ basis @ \
        Matrix.Scale(radius * 0.14, 4)
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = panel
    scene.render.image_settings.file_format = "PNG"
    scene.world = bpy.data.worlds.new("w")
    scene.world.color = (0.82, 0.84, 0.87)
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "VERTEX"
    scene.display.render_aa = "8"
    path = os.path.join(folder, "_panel_%s.png" % name)
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    tiles.append(np.array(img.pixels[:]).reshape(panel[1], panel[0], 4))
    os.remove(path)

strip = np.concatenate(tiles, axis=1)
img = bpy.data.images.new("strip", width=strip.shape[1], height=strip.shape[0])
img.pixels = strip.ravel()
img.filepath_raw = out
img.file_format = "PNG"
img.save()
