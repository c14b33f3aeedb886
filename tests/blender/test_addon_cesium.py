"""A CesiumMan variant with its armature, without a single manual step:
starter net from the armature, connect, bind; then the walk clip moves the
variant through the net, and it stays close to CesiumMan's own skin.

The variants (../shared/data/cesium_man/variants) are OBJ files in the glTF
mesh's own object space, so the OBJ object is placed where the imported
glTF mesh is: its world matrix times the OBJ importer's axis change.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

import addon_support as t  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402

t.empty_scene()
t.enable_addon()
import curvenet  # noqa: E402
from curvenet_blender import core  # noqa: E402

CESIUM = os.path.join(t.DATA, "cesium_man")
VARIANT = os.environ.get("CURVENET_CESIUM_VARIANT", "cesium_man_c_decimated.obj")
meshes, arms = t.import_gltf(os.path.join(CESIUM, "CesiumMan.glb"))
skin, arm = meshes[0], arms[0]
before = set(bpy.data.objects)
bpy.ops.wm.obj_import(filepath=os.path.join(CESIUM, "variants", VARIANT))
variant = [o for o in bpy.data.objects if o not in before][0]
variant.matrix_world = skin.matrix_world @ variant.matrix_world
bpy.context.view_layer.update()
t.check(len(variant.data.polygons) < len(skin.data.polygons), "%s: %d faces" % (VARIANT, len(variant.data.polygons)))

# Starter, connect, bind: three operators, nothing by hand.
t.select(variant, arm)
t.check(bpy.ops.curvenet.starter() == {"FINISHED"}, bpy.context.scene.curvenet.status)
t.select(variant)
t.check(bpy.ops.curvenet.connect() == {"FINISHED"}, "Connect: " + bpy.context.scene.curvenet.status)
rep = core.connect_result(variant)["report"]
t.check(rep["ok"] and rep["regions"] == rep["expected_regions"] and rep["unmapped_faces"] == 0, "the counts agree")
t.select(variant, arm)
t.check(bpy.ops.curvenet.bind() == {"FINISHED"}, "Bind: " + bpy.context.scene.curvenet.status)


def world_mesh(obj, name):
    """The evaluated surface in world space, as a curvenet.Mesh."""
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    me = ev.to_mesh()
    W = np.array(obj.matrix_world)
    V = np.array([v.co[:] for v in me.vertices]) @ W[:3, :3].T + W[:3, 3]
    F = [list(p.vertices) for p in me.polygons]
    ev.to_mesh_clear()
    return curvenet.Mesh(V, F, source=name)


rest = curvenet.compare(world_mesh(variant, "variant"), world_mesh(skin, "skin"))
t.check(rest["mean_percent"] < 1.0, "at rest the variant lies on the skin (%.3f%% mean)" % rest["mean_percent"])

# The walk: the glTF clip is the armature's action.
t.check(arm.animation_data is not None and arm.animation_data.action is not None, "the armature has its walk")
start, end = (int(x) for x in arm.animation_data.action.frame_range)
scene = bpy.context.scene
worst = 0.0
for frame in np.linspace(start, end, 5).astype(int):
    scene.frame_set(int(frame))
    bpy.context.view_layer.update()
    got = t.evaluated_positions(variant)
    # The same frame through the binding, with the matrices taken here.
    binding = core.state(variant).binding
    O, A = variant.matrix_world, arm.matrix_world
    M = np.array(
        [
            np.array(O.inverted() @ A @ arm.pose.bones[n].matrix @ arm.pose.bones[n].bone.matrix_local.inverted()
                     @ A.inverted() @ O)
            for n in binding.joint_names
        ]
    )
    want = binding.deform(M)
    t.check(np.abs(got - want).max() < 1e-6 * max(1.0, np.abs(want).max()), "frame %d equals Binding.deform" % frame)
    d = curvenet.compare(world_mesh(variant, "variant"), world_mesh(skin, "skin"))
    worst = max(worst, d["mean_percent"])
    t.check(d["mean_percent"] < rest["mean_percent"] + 1.5,
            "frame %d: the variant follows the skin (%.3f%% of the diagonal on average)" % (frame, d["mean_percent"]))
print("CURVENET_TEST worst mean distance to the skin over the walk: %.3f%%" % worst)
t.render_workbench([variant], os.path.join(t.OUT, "cesium_walk.png"), colour="SINGLE",
                   size=(600, 800), view=(0.5, -1.0, 0.25), up=(0, 0, 1))
print("CURVENET_TEST all passed")
