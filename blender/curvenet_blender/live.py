"""Live deformation: posing the armature or scrubbing the timeline moves
every bound mesh through its Binding (core.update_live). The handlers skip
a mesh whose armature pose has not changed, so writing the positions (which
triggers another depsgraph update) does not loop."""

import bpy
from bpy.app.handlers import persistent

from . import core

_busy = False


def _update_all(depsgraph=None, force=False):
    global _busy
    if _busy:
        return
    _busy = True
    try:
        for obj in core.live_objects():
            try:
                if core.ensure_binding(obj) is not None:
                    core.update_live(obj, depsgraph, force=force)
            except Exception as e:  # a handler must not raise into Blender
                core.state(obj).error = str(e)
        for obj in core.previewed_objects():
            core.sync_previews(obj)
    finally:
        _busy = False


@persistent
def on_frame_change(scene, depsgraph=None):
    _update_all(depsgraph)


@persistent
def on_depsgraph_update(scene, depsgraph=None):
    # Only a pose or transform change of an armature, or a node handle moved,
    # can move a bound mesh or pose a previewed one.
    if depsgraph is not None:
        if not any(
            isinstance(u.id, bpy.types.Object)
            and (u.id.type == "ARMATURE" or (u.id.type == "EMPTY" and core.HANDLE_KEY in u.id))
            for u in depsgraph.updates
        ):
            return
    _update_all(depsgraph)


@persistent
def on_load(_dummy=None):
    core.STATE.clear()  # bindings are runtime caches: bind again on demand
    _update_all()


@persistent
def on_undo_redo(_scene=None, _dummy=None):
    # Undo and redo bring back the object's rig, deformation and shape key;
    # the bindings made from another rig are made again (ensure_binding).
    _update_all(force=True)
    # The status line says what the data is now, not what it said at that step.
    scene = bpy.context.scene
    obj = bpy.context.active_object
    if scene is not None and getattr(scene, "curvenet", None) is not None and core.has_rig(obj):
        rig = core.get_rig(obj)
        scene.curvenet.status = "After undo or redo: %s has %d nodes and %d profiles; playing: %s" % (
            obj.name, len(rig.nodes), len(rig.profiles), core.describe_deformation(obj))


HANDLERS = (
    (bpy.app.handlers.undo_post, on_undo_redo),
    (bpy.app.handlers.redo_post, on_undo_redo),
    (bpy.app.handlers.frame_change_post, on_frame_change),
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
    (bpy.app.handlers.load_post, on_load),
)


def register():
    for handlers, fn in HANDLERS:
        if fn not in handlers:
            handlers.append(fn)


def unregister():
    for handlers, fn in HANDLERS:
        if fn in handlers:
            handlers.remove(fn)
