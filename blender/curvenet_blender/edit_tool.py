"""The net editor's operators. Each edit is a non-modal operator with its own
undo step (scriptable as bpy.ops.curvenet.*, and what the tests drive); the
Edit Net tool is a modal shell that turns clicks and keys into those
operators. The selection is the scene's (selected_nodes, selected_profiles),
so undo brings it back with the net."""

import bpy
from bpy.props import CollectionProperty, FloatVectorProperty, StringProperty
from bpy_extras import view3d_utils

import curvenet

from . import core, edit
from .operators import (
    _MeshOperator,
    _attempt,
    _done,
    _event_ray,
    _mesh,
    _status,
    change_snap,
    hide_hint,
    redraw,
    show_hint,
)


def _ids(text):
    return [s for s in (t.strip() for t in text.split(",")) if s]


def selection(context):
    props = context.scene.curvenet
    return _ids(props.selected_nodes), _ids(props.selected_profiles)


def set_selection(context, nodes=(), profiles=()):
    props = context.scene.curvenet
    props.selected_nodes = ",".join(nodes)
    props.selected_profiles = ",".join(profiles)


class CurvenetPoint(bpy.types.PropertyGroup):
    co: FloatVectorProperty(name="Point", size=3, subtype="XYZ")


class _EditOperator(_MeshOperator):
    """An edit of the net: `edit(context, obj)` does it and returns the status
    message; a refusal (core.Refused, the engine's errors) changes nothing and is reported."""

    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        ok, message = _attempt(self, context, self.bl_label, lambda: self.edit(context, obj))
        return _done(self, context, message) if ok else {"CANCELLED"}


def _given_or_one(given, selected, what):
    """The id given to the operator, or else the one selected id."""
    chosen = given or _one(selected)
    if not chosen:
        raise core.Refused("Select one %s first." % what)
    return chosen


class CURVENET_OT_delete(_EditOperator, bpy.types.Operator):
    """Delete the selected nodes (with their profiles) and profiles (with the nodes they leave alone)"""

    bl_idname = "curvenet.delete"
    bl_label = "Delete"

    nodes: StringProperty(name="Nodes", description="Comma-separated node ids; empty: the selected nodes")
    profiles: StringProperty(name="Profiles", description="Comma-separated profile ids; empty: the selected ones")

    def edit(self, context, obj):
        nodes, profiles = selection(context)
        if self.nodes or self.profiles:
            nodes, profiles = _ids(self.nodes), _ids(self.profiles)
        rig = edit.delete(obj, nodes, profiles)
        set_selection(context)
        return "Deleted %d nodes and %d profiles: %d nodes, %d profiles left" % (
            len(nodes), len(profiles), len(rig.nodes), len(rig.profiles))


class CURVENET_OT_move_node(_EditOperator, bpy.types.Operator):
    """Move a node to a point on the surface; its profiles follow"""

    bl_idname = "curvenet.move_node"
    bl_label = "Move Node"

    node: StringProperty(name="Node", description="Empty: the one selected node")
    location: FloatVectorProperty(name="Location", size=3, subtype="XYZ", description="Object space")

    def edit(self, context, obj):
        node = _given_or_one(self.node, selection(context)[0], "node to move")
        edit.move_node(obj, node, tuple(self.location))
        return "Moved node %s" % node


class CURVENET_OT_split_profile(_EditOperator, bpy.types.Operator):
    """Insert a node on a profile, at its point nearest to a location"""

    bl_idname = "curvenet.split_profile"
    bl_label = "Split Profile"

    profile: StringProperty(name="Profile", description="Empty: the one selected profile")
    location: FloatVectorProperty(name="Location", size=3, subtype="XYZ", description="Object space")

    def edit(self, context, obj):
        profile = _given_or_one(self.profile, selection(context)[1], "profile to split")
        _rig, node, new = edit.split(obj, profile, tuple(self.location))
        set_selection(context, [node])
        return "Split %s at the new node %s; the new profile %s goes on" % (profile, node, new)


class CURVENET_OT_merge_nodes(_EditOperator, bpy.types.Operator):
    """Merge the second selected node into the first (the profiles between them go)"""

    bl_idname = "curvenet.merge_nodes"
    bl_label = "Merge Nodes"

    kept: StringProperty(name="Kept", description="Empty: the first selected node")
    merged: StringProperty(name="Merged", description="Empty: the second selected node")

    def edit(self, context, obj):
        nodes = selection(context)[0]
        kept = self.kept or (nodes[0] if len(nodes) == 2 else "")
        merged = self.merged or (nodes[1] if len(nodes) == 2 else "")
        if not kept or not merged:
            raise core.Refused("Select exactly two nodes: the second is merged into the first.")
        edit.merge(obj, kept, merged)
        set_selection(context, [kept])
        return "Merged node %s into %s" % (merged, kept)


class CURVENET_OT_reroute_profile(_EditOperator, bpy.types.Operator):
    """Route a profile anew through points on the surface, between its same two nodes"""

    bl_idname = "curvenet.reroute_profile"
    bl_label = "Reroute Profile"

    profile: StringProperty(name="Profile", description="Empty: the one selected profile")
    points: CollectionProperty(type=CurvenetPoint)

    def edit(self, context, obj):
        profile = _given_or_one(self.profile, selection(context)[1], "profile to reroute")
        pts = [tuple(p.co) for p in self.points]
        edit.reroute(obj, profile, pts)
        return "Rerouted %s through %d points" % (profile, len(pts))


def _run(name, **properties):
    """Runs an edit operator from the Edit Net tool as a button would: an
    operator called from Python pushes no undo step, so the tool pushes it."""
    cls = getattr(bpy.types, "CURVENET_OT_" + name)
    result = getattr(bpy.ops.curvenet, name)(**properties)
    if result == {"FINISHED"}:
        bpy.ops.ed.undo_push(message="Curvenet: " + cls.bl_label)
    return result


def _one(ids):
    return ids[0] if len(ids) == 1 else ""


EDIT_HINT = ("Edit Net: click select (Shift adds), drag a box | G move node | K split profile at mouse | "
             "M merge 2 nodes | R reroute profile (click points, Enter) | X delete | [ ] snap | Ctrl+Z undo | "
             "Enter/Esc finish")


class CURVENET_OT_edit_net(_MeshOperator, bpy.types.Operator):
    """Edit the net in the viewport: select nodes and profiles (click, Shift, box), move (G),
    split (K), merge (M), reroute (R), delete (X). Every edit is one undo step"""

    bl_idname = "curvenet.edit_net"
    bl_label = "Edit Net"
    bl_options = {"REGISTER"}

    @property
    def obj(self):
        return bpy.data.objects.get(self.obj_name)

    def invoke(self, context, event):
        if context.area is None or context.area.type != "VIEW_3D":
            self.report({"WARNING"}, "Edit Net works in a 3D view")
            return {"CANCELLED"}
        obj = _mesh(context)
        if not core.has_rig(obj):
            self.report({"ERROR"}, "%s has no net yet: draw one or make a starter net" % obj.name)
            return {"CANCELLED"}
        self.obj_name = obj.name
        self.mode = "SELECT"  # or GRAB, ROUTE, BOX
        self.press = None  # where a left press started (region pixels)
        self.route = []
        context.window_manager.modal_handler_add(self)
        show_hint(context, "edit", EDIT_HINT)
        _status(context, EDIT_HINT)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        context.area.tag_redraw()
        obj = self.obj
        if obj is None:
            return self._finish(context, {"CANCELLED"})
        try:
            return self._step(context, event, obj)
        except curvenet.Error as e:
            self.report({"WARNING"}, str(e))
            _status(context, "Edit Net: %s" % e)
            self.mode = "SELECT"
            return {"RUNNING_MODAL"}

    def _finish(self, context, result):
        obj = self.obj
        if obj is not None:
            edit.end_preview(obj)
        hide_hint(context, "edit")
        return result

    def _step(self, context, event, obj):
        press = event.value == "PRESS"
        if self.mode == "GRAB":
            if event.type == "MOUSEMOVE":
                hit = core.surface_hit(obj, *_event_ray(context, event))
                if hit is not None:  # the profiles traced live where the node would go
                    shown = edit.preview_move(obj, self.grabbed, hit) is not None
                    _status(context, "Edit Net: move node %s; click to place it, Esc cancels%s" % (
                        self.grabbed, "" if shown else " (its profiles do not trace there)"))
                return {"RUNNING_MODAL"}
            if event.type == "LEFTMOUSE" and press:
                hit = core.surface_hit(obj, *_event_ray(context, event))
                edit.end_preview(obj)
                self.mode = "SELECT"
                if hit is None:
                    _status(context, "Edit Net: off the mesh; the node stays")
                    return {"RUNNING_MODAL"}
                _run("move_node", node=self.grabbed, location=tuple(hit))
                return {"RUNNING_MODAL"}
            if event.type in {"ESC", "RIGHTMOUSE"} and press:
                edit.end_preview(obj)
                self.mode = "SELECT"
                _status(context, "Edit Net: move cancelled")
            return {"RUNNING_MODAL"}
        if self.mode == "ROUTE":
            if event.type == "LEFTMOUSE" and press:
                hit = core.surface_hit(obj, *_event_ray(context, event))
                if hit is None:
                    _status(context, "Edit Net: the click missed the mesh")
                else:
                    self.route.append(tuple(hit))
                    _status(context, "Edit Net: reroute %s, %d points; Enter applies, Esc cancels" % (
                        self.routed, len(self.route)))
                return {"RUNNING_MODAL"}
            if event.type in {"RET", "NUMPAD_ENTER"} and press:
                self.mode = "SELECT"
                _run("reroute_profile", profile=self.routed, points=[{"name": str(i), "co": p} for i, p in enumerate(self.route)])
                return {"RUNNING_MODAL"}
            if event.type in {"ESC", "RIGHTMOUSE"} and press:
                self.mode = "SELECT"
                _status(context, "Edit Net: reroute cancelled")
                return {"RUNNING_MODAL"}
            return {"PASS_THROUGH"} if event.type.startswith("MOUSE") or event.type.startswith("WHEEL") else {"RUNNING_MODAL"}
        if event.type in {"RET", "NUMPAD_ENTER", "ESC"} and press:
            _status(context, "Edit Net: finished")
            return self._finish(context, {"FINISHED"})
        if event.type == "LEFTMOUSE":
            if press:
                self.press = (event.mouse_region_x, event.mouse_region_y)
                return {"RUNNING_MODAL"}
            if event.value == "RELEASE" and self.press is not None:
                start, self.press = self.press, None
                end = (event.mouse_region_x, event.mouse_region_y)
                if abs(end[0] - start[0]) + abs(end[1] - start[1]) > 6:
                    self._box(context, obj, start, end, event.shift)
                else:
                    self._click(context, obj, event)
                return {"RUNNING_MODAL"}
        if not press:
            return {"PASS_THROUGH"}
        if change_snap(context, event):
            return {"RUNNING_MODAL"}
        nodes, profiles = selection(context)
        if event.type in {"X", "DEL"}:
            _run("delete")
            return {"RUNNING_MODAL"}
        if event.type == "G":
            if len(nodes) != 1:
                _status(context, "Edit Net: select one node to move it")
                return {"RUNNING_MODAL"}
            self.mode, self.grabbed = "GRAB", nodes[0]
            _status(context, "Edit Net: move node %s; click to place it, Esc cancels" % self.grabbed)
            return {"RUNNING_MODAL"}
        if event.type == "K":
            hit = core.surface_hit(obj, *_event_ray(context, event))
            picked = edit.pick(obj, *_event_ray(context, event), snap=context.scene.curvenet.snap)
            if hit is None or picked is None or picked[0] != "profile":
                _status(context, "Edit Net: point at a profile to split it")
                return {"RUNNING_MODAL"}
            _run("split_profile", profile=picked[1], location=tuple(hit))
            return {"RUNNING_MODAL"}
        if event.type == "M":
            _run("merge_nodes")
            return {"RUNNING_MODAL"}
        if event.type == "R":
            if len(profiles) != 1:
                _status(context, "Edit Net: select one profile to reroute it")
                return {"RUNNING_MODAL"}
            self.mode, self.routed, self.route = "ROUTE", profiles[0], []
            _status(context, "Edit Net: reroute %s: click points from its first node to its last; Enter applies" % profiles[0])
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}  # Ctrl+Z, view navigation: Blender's own

    def _click(self, context, obj, event):
        picked = edit.pick(obj, *_event_ray(context, event), snap=context.scene.curvenet.snap)
        nodes, profiles = selection(context) if event.shift else ([], [])
        if picked is None:
            set_selection(context, nodes, profiles)
            _status(context, "Edit Net: nothing there" if not event.shift else "Edit Net: the click picked nothing")
            return
        kind, pid = picked
        chosen = nodes if kind == "node" else profiles
        if pid in chosen and event.shift:
            chosen.remove(pid)
        elif pid not in chosen:
            chosen.append(pid)
        set_selection(context, nodes, profiles)
        bpy.ops.ed.undo_push(message="Curvenet: select")  # undo brings the selection back with the net
        text = "Edit Net: %s %s" % (kind, pid)
        if kind == "node":
            w = core.node_weights(obj, pid)
            if w:
                text += ": " + ", ".join("%s %.2f" % kv for kv in sorted(w.items()))
        _status(context, text)

    def _box(self, context, obj, start, end, extend):
        """Selects the nodes whose markers lie in the dragged rectangle."""
        x0, x1 = sorted((start[0], end[0]))
        y0, y1 = sorted((start[1], end[1]))
        W = obj.matrix_world
        nodes, profiles = selection(context) if extend else ([], [])
        for n in core.get_rig(obj).nodes:
            p = view3d_utils.location_3d_to_region_2d(context.region, context.region_data, W @ _vec(n.position))
            if p is not None and x0 <= p.x <= x1 and y0 <= p.y <= y1 and n.id not in nodes:
                nodes.append(n.id)
        set_selection(context, nodes, profiles)
        bpy.ops.ed.undo_push(message="Curvenet: box select")
        _status(context, "Edit Net: %d nodes selected" % len(nodes))


def _vec(p):
    from mathutils import Vector

    return Vector(tuple(p))


CLASSES = (
    CurvenetPoint,
    CURVENET_OT_delete,
    CURVENET_OT_move_node,
    CURVENET_OT_split_profile,
    CURVENET_OT_merge_nodes,
    CURVENET_OT_reroute_profile,
    CURVENET_OT_edit_net,
)
