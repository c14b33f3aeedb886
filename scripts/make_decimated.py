"""Writes a decimated copy of a skinned glTF/GLB: Blender's Decimate modifier
(collapse) at the given ratio, with the armature and the skin weights
(Blender interpolates the vertex groups) and the clips whose names are given
(Blender writes the file in its own axes and bone frames, so the copy
carries its own clips). Meshes of our own making for
the starter tests and bench/starter_pose (tests/data/); run again to
regenerate:

    blender -b --factory-startup --python-exit-code 1 --python scripts/make_decimated.py -- IN.glb RATIO OUT.glb [CLIP...]
"""

import sys

import bmesh
import bpy
import numpy

numpy.bool = bool  # Blender 3.4's glTF importer under Debian's numpy

args = sys.argv[sys.argv.index("--") + 1:]
source, ratio, out, keep = args[0], args[1], args[2], args[3:]
bpy.ops.wm.read_factory_settings(use_empty=True)
# Welded at import: vertices split at UV seams or flat shading would decimate into cracks.
bpy.ops.import_scene.gltf(filepath=source, merge_vertices=True)
meshes = [o for o in bpy.data.objects if o.type == "MESH"]
for o in bpy.data.objects:
    if o.type == "ARMATURE" and o.animation_data:
        o.animation_data.action = None
        for track in list(o.animation_data.nla_tracks):
            if not any(track.name.endswith(k) for k in keep):
                o.animation_data.nla_tracks.remove(track)
for mesh in meshes:
    bpy.context.view_layer.objects.active = mesh
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.remove_doubles(threshold=1e-7)
    bpy.ops.object.mode_set(mode="OBJECT")
    mod = mesh.modifiers.new("decimate", "DECIMATE")
    mod.decimate_type = "COLLAPSE"
    mod.ratio = float(ratio)
    mod.use_collapse_triangulate = True
    # Modifiers apply in order: the decimation goes before the armature.
    bpy.ops.object.modifier_move_to_index(modifier="decimate", index=0)
    bpy.ops.object.modifier_apply(modifier="decimate")
    bm = bmesh.new()
    bm.from_mesh(mesh.data)
    open_edges = sum(1 for e in bm.edges if not e.is_manifold)
    bm.free()
    print(mesh.name, "faces:", len(mesh.data.polygons), "open or non-manifold edges:", open_edges)
    if open_edges:
        raise SystemExit("the decimated mesh is not closed")
for action in list(bpy.data.actions):
    if not any(("|" + k) in action.name for k in keep):
        bpy.data.actions.remove(action)
bpy.ops.export_scene.gltf(filepath=out, export_format="GLB", export_animations=bool(keep), export_skins=True,
                          export_apply=False, export_nla_strips=True)
