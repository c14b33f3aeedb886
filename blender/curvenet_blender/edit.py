"""The net editor's non-modal core: picking, and every edit of a net as a
function of the mesh object. The geometry of each edit is the library's
(curvenet.remove_nodes, move_node, split_profile, merge_nodes,
reroute_profile, set_joint_weight), which validates the net after it; here
the edited curves are pulled onto the surface and traced, and the rig is set
only when they trace, so a refused edit changes nothing. The operators in
edit_tool.py make each edit one undo step."""

import numpy as np

import curvenet

from . import core


def pick(obj, origin, direction, snap=core.SNAP_FRACTION):
    """What a click under a world-space ray picks: ("node", id), or
    ("profile", id), or None when it picks nothing. A node within the snap
    radius wins; otherwise the profile whose traced path passes nearest, if
    it passes within twice the radius."""
    placed = core.place(obj, origin, direction, snap)
    if placed is None:
        return None
    p, node, radius = placed
    if node is not None:
        return ("node", node)
    best, best_d = None, 2.0 * radius
    for pid, path in core.traced_paths(obj).items():
        d = _distance_to_polyline(p, path)
        if d < best_d:
            best, best_d = pid, d
    return None if best is None else ("profile", best)


def _distance_to_polyline(p, path):
    a, b = path[:-1], path[1:]
    ab = b - a
    len2 = np.maximum((ab * ab).sum(1), 1e-300)
    t = np.clip(((p - a) * ab).sum(1) / len2, 0.0, 1.0)
    return float(np.sqrt((((a + t[:, None] * ab) - p) ** 2).sum(1)).min()) if len(a) else float("inf")


def _commit(obj, rig, changed=()):
    """Pulls the changed profiles' curves onto the surface, traces them
    (curvenet.EmbedError, and nothing changes, when one cannot be traced) and
    sets the rig."""
    for pid in changed:
        prof = rig.profile(pid)
        pts = np.asarray(prof.curve.points)
        if len(pts) > 2:
            inner = core.on_surface(obj, pts[1:-1])
            c = prof.curve
            c.points = np.vstack([pts[:1], inner, pts[-1:]])
            prof.curve = c
    if changed:
        core._trace(obj, rig, list(changed))
    core.set_rig(obj, rig)
    return rig


def _profiles_at(rig, node):
    return [p.id for p in rig.profiles if node in (p.from_, p.to)]


def delete(obj, nodes=(), profiles=()):
    """Deletes nodes (with their profiles) and profiles (with the nodes they
    leave on no profile). Returns the rig."""
    rig = core.get_rig(obj)
    nodes = [n for n in nodes if n]
    if nodes:
        rig = curvenet.remove_nodes(rig, nodes, obj.name)
    left = {p.id for p in rig.profiles}
    profiles = [p for p in profiles if p in left]
    if profiles:
        rig = curvenet.remove_profiles(rig, profiles, obj.name)
    if not nodes and not profiles:
        raise core.Refused("Select nodes or profiles to delete first.")
    return _commit(obj, rig)


def move_node(obj, node, point):
    """Moves a node to an object-space point (pulled onto the surface); its
    profiles follow and are traced again."""
    p = core.on_surface(obj, [point])[0]
    rig = curvenet.move_node(core.get_rig(obj), node, p, obj.name)
    return _commit(obj, rig, _profiles_at(rig, node))


def preview_move(obj, node, point):
    """The node's profiles as they would be traced with the node at `point`,
    without changing the rig: kept on the state for the overlay (a drag).
    Returns the state's preview, or None when they do not trace."""
    st = core.state(obj)
    p = core.on_surface(obj, [point])[0]
    try:
        rig = curvenet.move_node(core.get_rig(obj), node, p, obj.name)
        changed = _profiles_at(rig, node)
        for pid in changed:
            prof = rig.profile(pid)
            pts = np.asarray(prof.curve.points)
            if len(pts) > 2:
                c = prof.curve
                c.points = np.vstack([pts[:1], core.on_surface(obj, pts[1:-1]), pts[-1:]])
                prof.curve = c
        st.preview = {"paths": core._trace(obj, rig, changed, keep=False), "nodes": {node: p}}
    except curvenet.Error:
        st.preview = None
    return st.preview


def end_preview(obj):
    core.state(obj).preview = None


def move_node_to_ray(obj, node, origin, direction):
    hit = core.surface_hit(obj, origin, direction)
    if hit is None:
        raise core.Refused("The mouse is off the mesh: move the node onto its surface.")
    return move_node(obj, node, hit)


def split(obj, profile, point):
    """Inserts a node on a profile at the point of its curve nearest to
    `point` (object space). Returns (rig, new node, new profile)."""
    rig = core.get_rig(obj)
    t = curvenet.nearest_parameter(rig, profile, np.asarray(point, dtype=np.float64), obj.name)
    if not 0.0 < t < 1.0:
        raise core.Refused("Split %s between its ends, not at a node." % profile)
    rig, node, new = curvenet.split_profile(rig, profile, t, obj.name)
    return _commit(obj, rig, [profile, new]), node, new


def merge(obj, kept, merged):
    """Merges node `merged` into node `kept`."""
    rig = curvenet.merge_nodes(core.get_rig(obj), kept, merged, obj.name)
    return _commit(obj, rig, _profiles_at(rig, kept))


def reroute(obj, profile, points):
    """Routes a profile anew through object-space points (pulled onto the surface)."""
    via = core.on_surface(obj, points) if len(points) else np.zeros((0, 3))
    rig = curvenet.reroute_profile(core.get_rig(obj), profile, via, obj.name)
    return _commit(obj, rig, [profile])
