"""The viewport overlay: node markers and each profile's traced path, the
exact path the cut will follow, drawn with the gpu module. The geometry
comes from overlay_geometry(), which headless tests call; drawing needs a
window."""

import bpy
import numpy as np

from . import core

_handle = None

COLOURS = {
    "path": (0.1, 0.8, 1.0, 1.0),
    "failed": (1.0, 0.15, 0.1, 1.0),
    "node": (1.0, 0.85, 0.1, 1.0),
    "selected": (1.0, 0.3, 0.9, 1.0),
    "selected_path": (1.0, 0.3, 0.9, 1.0),
}


def _ids(text):
    return [s for s in (t.strip() for t in text.split(",")) if s]


def selected_nodes(scene):
    return _ids(scene.curvenet.selected_nodes)


def shown(obj):
    """The overlay lies at rest: it shows unless the mesh is deformed away from rest."""
    return not core.is_posed(obj)


def overlay_geometry(obj, scene):
    """World-space line segments and points to draw, by colour name."""
    rig = core.get_rig(obj)
    paths = dict(core.traced_paths(obj))
    preview = core.state(obj).preview or {}
    paths.update(preview.get("paths", {}))  # a node being dragged: its profiles where it would put them
    W = np.array(obj.matrix_world)

    def world(p):
        p = np.asarray(p, dtype=np.float64)
        return p @ W[:3, :3].T + W[:3, 3]

    result = core.connect_result(obj) or {}
    failed = result.get("failed_profile") or scene.curvenet.selected_profile
    chosen_profiles = set(_ids(scene.curvenet.selected_profiles))
    lines = {"path": [], "failed": [], "selected_path": []}
    for pid, path in paths.items():
        pts = world(path)
        seg = np.repeat(pts, 2, axis=0)[1:-1]
        kind = "failed" if pid == failed else "selected_path" if pid in chosen_profiles else "path"
        lines[kind].append(seg)
    chosen = set(selected_nodes(scene))
    points = {"node": [], "selected": []}
    moved = preview.get("nodes", {})
    for n in rig.nodes:
        points["selected" if n.id in chosen else "node"].append(world(moved.get(n.id, n.position)))
    out = {}
    for k, v in lines.items():
        out[k] = np.vstack(v) if v else np.zeros((0, 3))
    for k, v in points.items():
        out[k] = np.array(v) if v else np.zeros((0, 3))
    return out


def _towards_viewer(geo, rv3d, distance):
    """Moves the overlay a little towards the viewer, so that it shows over
    the region preview, which lies a hair outside the mesh."""
    if rv3d is None:
        return
    inv = np.array(rv3d.view_matrix.inverted())
    eye, back = inv[:3, 3], inv[:3, 2]  # the view's position, and its +z (towards the viewer)
    for key, pts in geo.items():
        if len(pts) == 0:
            continue
        if rv3d.is_perspective:
            d = eye - pts
            d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        else:
            d = np.broadcast_to(back, pts.shape)
        geo[key] = pts + distance * d


def _shader():
    import gpu

    for name in ("UNIFORM_COLOR", "3D_UNIFORM_COLOR"):
        try:
            return gpu.shader.from_builtin(name)
        except (ValueError, SystemError):
            continue
    return None


def _draw():
    import gpu
    from gpu_extras.batch import batch_for_shader

    from . import operators

    obj = operators._mesh(bpy.context)  # the mesh, also when its armature was selected last
    if not core.has_rig(obj) or not shown(obj):
        return
    try:
        geo = overlay_geometry(obj, bpy.context.scene)
    except Exception:
        return
    shader = _shader()
    if shader is None:
        return
    _towards_viewer(geo, bpy.context.region_data, 3 * core.PREVIEW_LIFT * core.state(obj).diagonal)
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.line_width_set(3.0)
    gpu.state.point_size_set(9.0)
    for key in ("path", "selected_path", "failed"):
        if len(geo[key]):
            batch = batch_for_shader(shader, "LINES", {"pos": geo[key].astype(np.float32).tolist()})
            shader.bind()
            shader.uniform_float("color", COLOURS[key])
            batch.draw(shader)
    for key in ("node", "selected"):
        if len(geo[key]):
            batch = batch_for_shader(shader, "POINTS", {"pos": geo[key].astype(np.float32).tolist()})
            shader.bind()
            shader.uniform_float("color", COLOURS[key])
            batch.draw(shader)
    gpu.state.depth_test_set("NONE")
    gpu.state.line_width_set(1.0)
    gpu.state.point_size_set(1.0)


def register():
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_VIEW")


def unregister():
    global _handle
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        _handle = None
