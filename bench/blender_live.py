"""Live deformation in Blender, measured headless: how many frames a second
scrubbing the timeline gives, with each mesh bound through the add-on, against
the same scene deformed by its own Armature modifier.

    blender -b --factory-startup --python bench/blender_live.py -- BUILD_DIR DATA_DIR [FRAMES]

For each shared mesh it prints one row: vertices, the median milliseconds per
frame (frame_set plus the evaluation of the deformed mesh, which is what the
viewport waits for), frames per second, and the part spent in the add-on's
handler (skinning matrices from the pose bones, Binding.deform into a
preallocated buffer, foreach_set into the shape key). Then the same with a
node pulled by a keyed handle: over the net's own deformation (live), and
layered over the Armature modifier (layer), each with its handler's time.
All rows come from one run on one machine; only ratios within a run compare.
"""

import os
import statistics
import sys
import time

import bpy
import numpy

numpy.bool = bool  # Blender 3.4's glTF importer needs it under Debian's numpy

args = sys.argv[sys.argv.index("--") + 1 :]
BUILD, DATA = (os.path.abspath(a) for a in args[:2])
FRAMES = int(args[2]) if len(args) > 2 else 120
sys.path.insert(0, os.path.join(BUILD, "blender"))
bpy.ops.wm.read_factory_settings(use_empty=True)
import addon_utils  # noqa: E402

addon_utils.enable("curvenet_blender", default_set=True)
from curvenet_blender import core, live  # noqa: E402

HAND = os.path.join(DATA, "xr_tools_hand")
CASES = [("hand_l.gltf", HAND), ("Hand_low_L.gltf", HAND), ("CesiumMan.glb", os.path.join(DATA, "cesium_man"))]


def animate(arm, frames):
    """Keys every pose bone through a bend and back over the frames."""
    for i, pb in enumerate(arm.pose.bones):
        pb.rotation_mode = "XYZ"
        for f, angle in ((1, 0.0), (frames // 2, 0.6 + 0.02 * i), (frames, 0.0)):
            pb.rotation_euler = (angle, 0.0, 0.3 * angle)
            pb.keyframe_insert("rotation_euler", frame=f)


def scrub(obj, frames):
    scene = bpy.context.scene
    times = []
    for f in range(1, frames + 1):
        t0 = time.perf_counter()
        scene.frame_set(f)
        deps = bpy.context.evaluated_depsgraph_get()
        obj.evaluated_get(deps).to_mesh()  # the viewport evaluates the deformed mesh
        obj.evaluated_get(deps).to_mesh_clear()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1000


# The handler's own time, per call.
handler_times = []
_update = core.update_live


def timed_update(obj, depsgraph=None, force=False):
    t0 = time.perf_counter()
    r = _update(obj, depsgraph, force)
    handler_times.append(time.perf_counter() - t0)
    return r


core.update_live = timed_update

def pull(c2, obj, frames):
    """A handle on a node of the middle bone, keyed at rest at the ends and
    pulled by 2 % of the diagonal half way."""
    scene = bpy.context.scene
    scene.frame_set(1)
    rig = c2.get_rig(obj)
    node = rig.nodes[len(rig.nodes) // 2].id
    h = c2.add_node_handle(obj, node)
    for f in (1, frames):
        h.keyframe_insert("location", frame=f)
    h.location.x += 0.02 * c2.state(obj).diagonal
    h.keyframe_insert("location", frame=frames // 2)


def timed_scrub(obj, frames):
    scrub(obj, 5)
    handler_times.clear()
    ms = scrub(obj, frames)
    return ms, statistics.median(handler_times) * 1000 if handler_times else float("nan")


print("| mesh | vertices | Armature modifier ms/frame | curvenet ms/frame | curvenet fps | handler ms | ratio "
      "| live + handle ms (handler) | layer + handle ms (handler) | layer + handle fps |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for name, folder in CASES:
    path = os.path.join(folder, name)
    if not os.path.exists(path):
        continue
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("curvenet_blender", default_set=True)
    from curvenet_blender import core as c2  # noqa: E402

    c2.update_live = timed_update
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=path)
    new = [o for o in bpy.data.objects if o not in before]
    obj = [o for o in new if o.type == "MESH"][0]
    arm = [o for o in new if o.type == "ARMATURE"][0]
    if arm.animation_data:
        arm.animation_data.action = None
    animate(arm, FRAMES)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, FRAMES
    scrub(obj, 5)
    lbs = scrub(obj, FRAMES)
    c2.starter(obj, arm)
    c2.bind(obj, arm)
    ours, handler = timed_scrub(obj, FRAMES)
    pull(c2, obj, FRAMES)
    live_pulled, live_handler = timed_scrub(obj, FRAMES)
    c2.bind(obj, arm, layer=True)
    layer_pulled, layer_handler = timed_scrub(obj, FRAMES)
    print("| %s | %d | %.2f | %.2f | %.0f | %.2f | %.2f | %.2f (%.2f) | %.2f (%.2f) | %.0f |" % (
        name, len(obj.data.vertices), lbs, ours, 1000.0 / ours, handler, ours / lbs, live_pulled, live_handler,
        layer_pulled, layer_handler, 1000.0 / layer_pulled))
live.unregister()
