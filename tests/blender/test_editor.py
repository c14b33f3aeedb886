"""The add-on as a rigger's editor (issue 25), headless, on the shared hand
with its armature, through the operators and Blender's own undo:

1. the armature selected last, as for Ctrl+P; the starter's reasons kept;
2. every net edit (delete, move, split, merge, reroute, a node weight) is one
   undo step: after it the net passes the engine's validation, undo brings
   the net back exactly, redo the edit;
3. Connect's result follows undo; an empty net is refused in a sentence;
4. one deformation at a time, through every sequence of the tester's report;
5. renaming the armature, saving and loading keep the binding and the
   deformation;
6. feedback: the snap radius on a thin finger, a missed click, a first click
   that leaves no orphan node, the bake range from the clip.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

import addon_support as t  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Quaternion, Vector  # noqa: E402

t.empty_scene()
t.enable_addon()
import curvenet  # noqa: E402
from curvenet_blender import core, draw, edit, operators  # noqa: E402

HAND = os.path.join(t.DATA, "xr_tools_hand")
meshes, arms = t.import_gltf(os.path.join(HAND, "hand_l.gltf"))
MESH, ARM = meshes[0].name, arms[0].name


def objects():
    """The mesh and the armature, looked up anew: an undo replaces every object."""
    return bpy.data.objects[MESH], bpy.data.objects[ARM]


def rig_text():
    return objects()[0].get(core.RIG_KEY, "")


def valid():
    obj, _ = objects()
    curvenet.validate_rig(core.get_rig(obj), "after the edit")
    return True


def press(name, **properties):
    """An operator as the UI runs it: Blender pushes an undo step after an
    operator marked UNDO that finishes (a call from Python alone does not)."""
    cls = getattr(bpy.types, "CURVENET_OT_" + name)
    try:
        result = getattr(bpy.ops.curvenet, name)(**properties)
    except RuntimeError as e:  # an operator's ERROR report, raised to a Python caller
        print("refused:", e)
        return {"CANCELLED"}
    if result == {"FINISHED"} and "UNDO" in cls.bl_options:
        bpy.ops.ed.undo_push(message=cls.bl_label)
    return result


def undo():
    bpy.ops.ed.undo()


def redo():
    bpy.ops.ed.redo()


def check_undoable(label, run, changed):
    """Runs one edit; checks the engine validates the net after it, that one
    undo brings the net back exactly and one redo the edit."""
    before = rig_text()
    t.check(run() == {"FINISHED"}, "%s: %s" % (label, bpy.context.scene.curvenet.status))
    after = rig_text()
    t.check(after != before and valid() and changed(), "%s changes the net, which stays valid" % label)
    undo()
    t.check(rig_text() == before, "undo of %s brings the net back exactly" % label)
    redo()
    t.check(rig_text() == after, "redo of %s makes it again" % label)
    undo()  # the next edit starts from the same net


obj, arm = objects()
rest = np.array([v.co[:] for v in obj.data.vertices])

# --- 1. the armature selected last; the starter's reasons --------------------
t.select(arm, obj)  # the mesh selected, the armature active: Ctrl+P's habit
t.check(operators._mesh(bpy.context) == obj and operators._armature(bpy.context) == arm,
        "with the armature active, the selected mesh is the one worked on")
t.check(press("starter") == {"FINISHED"}, "Starter: " + bpy.context.scene.curvenet.status)
obj, arm = objects()
notes = core.starter_notes(obj)
t.check(all(isinstance(j, str) and reason for j, reason in notes), "the starter's reasons are kept: %s" % notes[:3])
from types import SimpleNamespace  # noqa: E402
from unittest import mock  # noqa: E402

from curvenet_blender import ui  # noqa: E402

layout = mock.MagicMock()
ui.CURVENET_PT_panel.draw(SimpleNamespace(layout=layout), bpy.context)
drawn = str(layout.mock_calls)
t.check("curvenet.edit_net" in drawn, "the panel offers the net editor")
t.check(all(j in drawn for j, _ in notes[:12]) and ("without a ring" in drawn or not notes),
        "the panel lists the joints without a ring, each a button that selects its bone")
if notes:
    t.check(press("select_bone", bone=notes[0][0]) == {"FINISHED"}
            and objects()[1].data.bones.active.name == notes[0][0], "a reason's joint is selected from the panel")
t.check(core.make_armature(objects()[0]) == objects()[1], "Make Armature finds the character's own armature: no duplicate")

# --- 2. every edit is one undo step -----------------------------------------
obj, arm = objects()
rig = core.get_rig(obj)
paths = core.traced_paths(obj)
t.select(objects()[0])
# A profile and its two ends, away from the rest: the longest path, whose
# middle is clear of every node.
prof = max(rig.profiles, key=lambda p: float(np.sum(np.linalg.norm(np.diff(np.asarray(paths[p.id]), axis=0), axis=1))))
pid, a, b = prof.id, prof.from_, prof.to
path = paths[pid]
print("the profile edited:", pid, "with", len(path), "points")
mid = path[len(path) // 2]

check_undoable("delete a node", lambda: press("delete", nodes=a),
               lambda: core.get_rig(objects()[0]).node_index(a) < 0)
check_undoable("delete a profile", lambda: press("delete", profiles=pid),
               lambda: all(p.id != pid for p in core.get_rig(objects()[0]).profiles))

# Move node a a little along the surface: its profiles are traced anew and end there.
obj, arm = objects()
pa = np.asarray(core.get_rig(obj).node(a).position)
toward = pa + 0.25 * (np.asarray(path[min(3, len(path) - 1)]) - pa)
target = core.on_surface(obj, [toward])[0]


def moved():
    o = objects()[0]
    r = core.get_rig(o)
    p = np.asarray(r.node(a).position)
    trace = core.traced_paths(o)[pid]
    end = trace[0] if r.profile(pid).from_ == a else trace[-1]
    print("moved: node %.3g from the target, path end %.3g from the node (diagonal %.3g)" % (
        np.linalg.norm(p - target), np.linalg.norm(end - p), core.state(o).diagonal))
    return np.linalg.norm(p - target) < 1e-6 * core.state(o).diagonal and np.linalg.norm(end - p) < 1e-3 * core.state(o).diagonal


# While G drags a node, the overlay shows its profiles traced where it would go; the rig is unchanged.
before = rig_text()
preview = edit.preview_move(obj, a, target)
geo = draw.overlay_geometry(obj, bpy.context.scene)
W = np.array(obj.matrix_world)
want_marker = W[:3, :3] @ core.on_surface(obj, [target])[0] + W[:3, 3]
t.check(preview is not None and pid in preview["paths"] and rig_text() == before
        and np.min(np.linalg.norm(np.vstack([geo["node"], geo["selected"]]) - want_marker, axis=1)) < 1e-9,
        "dragging a node traces its profiles live for the overlay, without changing the net")
edit.end_preview(obj)
check_undoable("move a node", lambda: press("move_node", node=a, location=tuple(target)), moved)
obj, arm = objects()
n_nodes = len(core.get_rig(obj).nodes)
check_undoable("split a profile", lambda: press("split_profile", profile=pid, location=tuple(mid)),
               lambda: len(core.get_rig(objects()[0]).nodes) == n_nodes + 1)
# Split, keep it, then merge the new node back into an end: one undo step each.
press("split_profile", profile=pid, location=tuple(mid))
split_rig = core.get_rig(objects()[0])
new_node = bpy.context.scene.curvenet.selected_nodes
t.check(split_rig.node_index(new_node) >= 0, "the split selects its new node (%s)" % new_node)
check_undoable("merge two nodes", lambda: press("merge_nodes", kept=b, merged=new_node),
               lambda: core.get_rig(objects()[0]).node_index(new_node) < 0)
undo()  # back before the split
t.check(len(core.get_rig(objects()[0]).nodes) == n_nodes, "undo takes the split back too")
route = [tuple(p) for p in path[1:-1:max(1, len(path) // 5)]]
check_undoable("reroute a profile",
               lambda: press("reroute_profile", profile=pid, points=[{"name": str(i), "co": p} for i, p in enumerate(route)]),
               lambda: len(core.get_rig(objects()[0]).profile(pid).curve.points) == len(route) + 2)
# A refused edit changes nothing: merging a node with itself.
before = rig_text()
t.check(press("merge_nodes", kept=a, merged=a) == {"CANCELLED"} and rig_text() == before,
        "a refused edit changes nothing: " + bpy.context.scene.curvenet.status)
t.check("(" not in bpy.context.scene.curvenet.status.split(":", 1)[1][:2], "the refusal reads as a sentence")

# Picking: a click on a node picks it, one on a profile's path picks the profile.
obj, arm = objects()
normal_ray = lambda p: (obj.matrix_world @ Vector(tuple(p + 0.2 * core.state(obj).diagonal * _outward(p))),  # noqa: E731
                        -(obj.matrix_world.to_3x3() @ Vector(tuple(_outward(p)))))


def _outward(p):
    near = core.surface_bvh(obj).find_nearest(Vector(tuple(p)))
    return np.array(near[1][:])


node_p = np.asarray(core.get_rig(obj).node(a).position)
t.check(edit.pick(obj, *normal_ray(node_p)) == ("node", a), "a click on node %s picks it" % a)
t.check(edit.pick(obj, *normal_ray(mid)) == ("profile", pid), "a click on profile %s's path picks it" % pid)

# --- 3. Connect's result follows undo; an empty net is refused ------------------
t.select(objects()[0])
bpy.ops.ed.undo_push(message="before connect")
t.check(press("connect") == {"FINISHED"}, "Connect: " + bpy.context.scene.curvenet.status)
t.check(core.connect_result(objects()[0])["ok"], "the result is kept with the net")
press("delete", profiles=pid)
t.check(core.connect_result(objects()[0]) is None, "after an edit the old result is not shown as the net's")
undo()
t.check(core.connect_result(objects()[0]) is not None and core.connect_result(objects()[0])["ok"],
        "undo of the edit brings the net and its result back")
undo()
t.check(core.connect_result(objects()[0]) is None, "undo of Connect takes its SUCCESS away")
redo()
redo()
saved_rig = rig_text()
obj, arm = objects()
t.select(objects()[0])
press("clear")
t.check(press("connect") == {"CANCELLED"} and "no net yet" in bpy.context.scene.curvenet.status,
        "an empty net is refused: " + bpy.context.scene.curvenet.status)
t.select(*objects())
t.check(press("bind") == {"CANCELLED"} and "no net yet" in bpy.context.scene.curvenet.status,
        "and not bound: " + bpy.context.scene.curvenet.status)
undo()
t.check(rig_text() == saved_rig, "undo of Clear Net brings the net back")

# --- 4. one deformation at a time -------------------------------------------
WANT = {
    "rest": set(),
    "skin": {"ARMATURE"},
    "live": {"shape key"},
    "layer": {"ARMATURE", "shape key"},
    "cache": {"MESH_CACHE"},
    "groups": {"ARMATURE"},
}


def check_one(label, kind):
    obj, _ = objects()
    active = core.active_deformers(obj)
    kinds = {x[1] if x[0] == "modifier" else "shape key" for x in active}
    t.check(core.deformation(obj) == kind and kinds == WANT[kind] and len(active) == len(WANT[kind]),
            "%s: one deformation plays, %s (%s)" % (label, kind, active))


def pose_finger(degrees, frame=None):
    _, arm = objects()
    pb = arm.pose.bones["Index_Proximal_L"]
    pb.rotation_mode = "QUATERNION"
    pb.rotation_quaternion = Quaternion((1, 0, 0), np.radians(degrees))
    if frame is not None:
        pb.keyframe_insert("rotation_quaternion", frame=frame)
    bpy.context.view_layer.update()
    bpy.context.view_layer.update()


def moved_from_rest():
    return float(np.abs(t.evaluated_positions(objects()[0]) - rest).max())


check_one("as imported", "skin")

pose_finger(0, 1)
pose_finger(70, 9)
bpy.context.scene.frame_set(5)
t.select(*objects())
t.check(press("bind") == {"FINISHED"}, "Bind: " + bpy.context.scene.curvenet.status)
check_one("Bind", "live")
t.check("playing: Curvenet, live" in bpy.context.scene.curvenet.status, "Bind says what plays: " + bpy.context.scene.curvenet.status)
t.check(core.clip_range(objects()[0]) == (1, 9), "the bake range is the clip's: %s" % (core.clip_range(objects()[0]),))
pc2 = os.path.join(t.OUT, "editor_bake.pc2")
t.check(press("bake_cache", filepath=pc2) == {"FINISHED"}, "Bake Cache: " + bpy.context.scene.curvenet.status)
check_one("Bind, Bake Cache", "cache")
t.check("frames 1-9" in bpy.context.scene.curvenet.status, "the cache holds the clip's frames: " + bpy.context.scene.curvenet.status)
t.select(objects()[0], objects()[1])
t.check(press("bake_vertex_groups") == {"FINISHED"}, "Bake to Vertex Groups: " + bpy.context.scene.curvenet.status)
check_one("Bind, Bake Cache, Bake to Vertex Groups", "groups")
bpy.context.scene.frame_set(8)
t.check(moved_from_rest() > 0.002, "the baked groups move the finger at frame 8")
# After a cache, a new Bind is what plays (the mesh moves, not only the shape key).
t.check(press("bind") == {"FINISHED"}, "Bind again")
t.check(press("bake_cache", filepath=pc2) == {"FINISHED"}, "Bake Cache again")
t.check(press("bind") == {"FINISHED"}, "Bind after the cache")
check_one("Bake Cache, Bind", "live")
bpy.context.scene.frame_set(9)
obj, arm = objects()
want = core.state(obj).binding.deform(core.skinning_matrices(obj, arm))
err = np.abs(t.evaluated_positions(obj) - want).max()
t.check(err < 4e-7 * np.abs(want).max() and moved_from_rest() > 0.002, "after a cache, Bind plays (error %.2g)" % err)
t.check(press("bake_cache", filepath=pc2) == {"FINISHED"}, "Bake Cache once more")
t.check(press("bake_cache", filepath=pc2) == {"FINISHED"}, "and a bake over that bake")
check_one("Bake Cache, Bake Cache", "cache")
t.check(press("unbind") == {"FINISHED"}, "Unbind")
check_one("Bake Cache, Unbind", "skin")
t.check(press("bind") == {"FINISHED"}, "Bind")
bpy.context.scene.curvenet.layer = True
t.check(press("bind") == {"FINISHED"}, "Bind, layered: " + bpy.context.scene.curvenet.status)
check_one("Bind over the Armature", "layer")
bpy.context.scene.curvenet.layer = False
t.check(press("bind") == {"FINISHED"}, "Bind, not layered")
check_one("Bind over the Armature, then Bind", "live")
bpy.ops.ed.undo_push(message="bound")
t.check(press("unbind") == {"FINISHED"}, "Unbind")
check_one("Unbind", "skin")
undo()
check_one("undo of Unbind", "live")
# A weight change while bound, and its undo: the deformation follows the net each time.
obj, arm = objects()
node = core.get_rig(obj).nodes[0].id
t.select(*objects())
before = t.evaluated_positions(obj)
bpy.ops.ed.undo_push(message="before the weight")
t.check(press("set_node_weight", nodes=node, bone="Index_Proximal_L", weight=1.0) == {"FINISHED"},
        "Set node weight: " + bpy.context.scene.curvenet.status)
undo()
bpy.context.view_layer.update()
bpy.context.view_layer.update()
obj, arm = objects()
want = core.ensure_binding(obj).deform(core.skinning_matrices(obj, arm))
t.check(np.abs(t.evaluated_positions(obj) - want).max() < 4e-7 * np.abs(want).max()
        and np.abs(t.evaluated_positions(obj) - before).max() < 1e-5,
        "undo of a weight brings the old deformation back, bound again to the old net")

# --- 5. rename, save, load ----------------------------------------------------
obj, arm = objects()
arm.name = "Renamed rig"
ARM = arm.name
pose_finger(40)
obj, arm = objects()
want = core.ensure_binding(obj).deform(core.skinning_matrices(obj, arm))
t.check(core.bound_armature(obj) == arm and np.abs(t.evaluated_positions(obj) - want).max() < 4e-7 * np.abs(want).max(),
        "renaming the armature keeps the deformation")
blend = os.path.join(t.OUT, "editor.blend")
bpy.ops.wm.save_as_mainfile(filepath=blend)
bpy.ops.wm.open_mainfile(filepath=blend)
obj, arm = objects()
check_one("after loading", "live")
pose_finger(55)
want = core.ensure_binding(obj).deform(core.skinning_matrices(obj, arm))
t.check(np.abs(t.evaluated_positions(obj) - want).max() < 4e-7 * np.abs(want).max(), "the loaded mesh follows its renamed armature")

# --- 6. feedback --------------------------------------------------------------
obj, arm = objects()
t.select(objects()[0])
core.unbind(obj)
pose_finger(0)
bone = arm.data.bones["Index_Intermediate_L"]
W = arm.matrix_world
centre = (W @ bone.head_local + W @ bone.tail_local) / 2
axis = (W @ bone.tail_local - W @ bone.head_local).normalized()
u = axis.orthogonal().normalized()
v = axis.cross(u)
hit = core.surface_ray(obj, centre + 0.0 * u, u)
radius = core.snap_radius(obj, hit[0], hit[1], fraction=0.2)
t.check(radius < 0.2 * core.state(obj).diagonal, "the snap radius on a finger is capped by its thickness (%.4f)" % radius)
placed_a = core.place(obj, centre, u, snap=0.2)
placed_b = core.place(obj, centre, v, snap=0.2)
t.check(np.linalg.norm(placed_a[0] - placed_b[0]) > radius, "two clicks a quarter turn apart round a finger stay two nodes")


snap = bpy.context.scene.curvenet.snap
t.check(operators.change_snap(bpy.context, SimpleNamespace(type="RIGHT_BRACKET", value="PRESS"))
        and abs(bpy.context.scene.curvenet.snap - 1.25 * snap) < 1e-6, "] grows the snap radius while drawing")
shell = t.draw_shell(MESH)
nodes_before = len(core.get_rig(obj).nodes)
shell._step(bpy.context, SimpleNamespace(type="LEFTMOUSE", value="PRESS", ctrl=False, shift=False,
                                         ray=(centre + axis * 100, axis)))
t.check(shell.reports and "missed" in shell.reports[-1][1], "a missed click is reported: %s" % shell.reports)
shell._step(bpy.context, SimpleNamespace(type="LEFTMOUSE", value="PRESS", ctrl=False, shift=False, ray=(centre, u)))
shell._step(bpy.context, SimpleNamespace(type="RET", value="PRESS", ctrl=False, shift=False, ray=None))
t.check(len(core.get_rig(objects()[0]).nodes) == nodes_before, "a stroke of one click leaves no orphan node")
bpy.context.scene.frame_set(9)
t.check(not draw.shown(objects()[0]), "posed by the clip, the overlay (curves at rest) hides")
bpy.context.scene.frame_set(1)
t.check(draw.shown(objects()[0]), "at the clip's rest frame the overlay shows")
print("CURVENET_TEST all passed")
