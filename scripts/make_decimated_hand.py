"""Writes tests/data/hand/hand_l_decimated.glb: the shared hand (hand_l_poses.glb,
CC0) decimated by Blender's Decimate modifier (collapse, ratio 0.2), with its
armature and skin weights (Blender interpolates the vertex groups) and no
clips. A second hand of our own making for bench/starter_pose and the
starter tests; run again to regenerate:

    blender -b --factory-startup --python-exit-code 1 --python scripts/make_decimated_hand.py -- DATA OUT.glb
"""

import sys

import bpy
import numpy

numpy.bool = bool  # Blender 3.4's glTF importer under Debian's numpy

data, out = sys.argv[sys.argv.index("--") + 1 :][:2]
bpy.ops.wm.read_factory_settings(use_empty=True)
# Welded at import: vertices split at UV seams would decimate into cracks.
bpy.ops.import_scene.gltf(filepath=data + "/xr_tools_hand/hand_l_poses.glb", merge_vertices=True)
mesh = [o for o in bpy.data.objects if o.type == "MESH"][0]
for o in bpy.data.objects:
    if o.type == "ARMATURE" and o.animation_data:
        o.animation_data.action = None
        for track in list(o.animation_data.nla_tracks):
            o.animation_data.nla_tracks.remove(track)
bpy.context.view_layer.objects.active = mesh
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.mesh.select_all(action="SELECT")
bpy.ops.mesh.remove_doubles(threshold=1e-6)
bpy.ops.object.mode_set(mode="OBJECT")
mod = mesh.modifiers.new("decimate", "DECIMATE")
mod.decimate_type = "COLLAPSE"
mod.ratio = 0.2
# Modifiers apply in order: the decimation goes before the armature.
bpy.ops.object.modifier_move_to_index(modifier="decimate", index=0)
bpy.ops.object.modifier_apply(modifier="decimate")
import bmesh  # noqa: E402

bm = bmesh.new()
bm.from_mesh(mesh.data)
open_edges = sum(1 for e in bm.edges if not e.is_manifold)
bm.free()
print("faces:", len(mesh.data.polygons), "open or non-manifold edges:", open_edges)
if open_edges:
    raise SystemExit("the decimated hand is not closed")
bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_animations=False, export_skins=True,
                          export_apply=False)
