# Headless Blender check of a PC2 point cache written by `curvenet animate`.
# Imports the rest mesh (OBJ), adds a Mesh Cache modifier with the axis
# settings docs/deform.md gives for OBJ imports, and compares the evaluated
# mesh with the frames of an OBJ sequence written by the same command.
#
#   blender -b --factory-startup --python check_mesh_cache.py -- REST.obj CACHE.pc2 SEQ_DIR FIRST LAST
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
rest, cache, seq, first, last = args[0], args[1], args[2], int(args[3]), int(args[4])

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.obj_import(filepath=rest)
obj = bpy.context.selected_objects[0]
mod = obj.modifiers.new("curvenet", "MESH_CACHE")
mod.cache_format = "PC2"
mod.filepath = cache
mod.forward_axis = "POS_Y"  # an OBJ import keeps the file's coordinates in the mesh
mod.up_axis = "POS_Z"       # and rotates the object instead: no axis change here
mod.frame_start = first     # the cache's first sample plays at the scene's frame `first`


def read_obj(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                out.append(tuple(float(x) for x in line.split()[1:4]))
    return out


worst = 0.0
scale = 0.0
for frame in range(first, last + 1):
    bpy.context.scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    mesh = obj.evaluated_get(depsgraph).to_mesh()
    expected = read_obj("%s/frame_%04d.obj" % (seq, frame))
    if len(mesh.vertices) != len(expected):
        print("CURVENET_CHECK vertex count %d != %d" % (len(mesh.vertices), len(expected)))
        sys.exit(1)
    for v, e in zip(mesh.vertices, expected):
        worst = max(worst, max(abs(v.co[i] - e[i]) for i in range(3)))
        scale = max(scale, max(abs(x) for x in e))
    obj.evaluated_get(depsgraph).to_mesh_clear()
print("CURVENET_CHECK max_error %.9g scale %.9g frames %d" % (worst, scale, last - first + 1))
