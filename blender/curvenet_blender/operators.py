"""The workflow's steps as operators: thin shells over core.py, so every
step can be scripted (bpy.ops.curvenet.*) and tested headless."""

import os

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras import view3d_utils
from bpy_extras.io_utils import ExportHelper, ImportHelper

import curvenet

from . import core


def _mesh(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "MESH" and not obj.get("curvenet_preview_of") else None


def _armature(context):
    for o in context.selected_objects:
        if o.type == "ARMATURE":
            return o
    return context.scene.curvenet.armature


def _target(context, source):
    for o in context.selected_objects:
        if o.type == "MESH" and o != source and not o.get("curvenet_preview_of"):
            return o
    return context.scene.curvenet.target


def _event_ray(context, event):
    """The world-space ray under the mouse: from the view's origin through the pixel."""
    xy = (event.mouse_region_x, event.mouse_region_y)
    origin = view3d_utils.region_2d_to_origin_3d(context.region, context.region_data, xy)
    direction = view3d_utils.region_2d_to_vector_3d(context.region, context.region_data, xy)
    return origin, direction


def _status(context, text):
    context.scene.curvenet.status = text.splitlines()[0] if text else ""


def _attempt(op, context, label, call, errors=(curvenet.Error,)):
    """Runs a core call; a refusal is reported in the info bar and the panel.
    Returns (ok, result)."""
    try:
        return True, call()
    except errors as e:
        op.report({"ERROR"}, str(e))
        _status(context, "%s: %s" % (label, e))
        return False, None


def _done(op, context, message, ok=True):
    _status(context, message)
    op.report({"INFO"} if ok else {"WARNING"}, message)
    return {"FINISHED"} if ok else {"CANCELLED"}


class _MeshOperator:
    @classmethod
    def poll(cls, context):
        return _mesh(context) is not None


class CURVENET_OT_draw(_MeshOperator, bpy.types.Operator):
    """Draw a net on the mesh: click to place nodes (a click near a node reuses it);
    each click after the first makes a profile, traced on the surface. Ctrl+Z removes
    the last profile; Enter or Esc finishes"""

    bl_idname = "curvenet.draw"
    bl_label = "Draw"
    bl_options = {"REGISTER"}

    def invoke(self, context, event):
        if context.area is None or context.area.type != "VIEW_3D":
            self.report({"WARNING"}, "Draw works in a 3D view")
            return {"CANCELLED"}
        self.obj = _mesh(context)
        self.previous = None
        self.stroke = []  # surface points the mouse passed over since the last click
        context.window_manager.modal_handler_add(self)
        _status(context, "Draw: click on the mesh; Ctrl+Z undoes a profile; Enter or Esc finishes")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        context.area.tag_redraw()
        try:
            return self._step(context, event)
        except curvenet.Error as e:  # a mesh the engine refuses: say why and stop
            self.report({"ERROR"}, str(e))
            _status(context, "Draw: " + str(e))
            return {"CANCELLED"}

    def _step(self, context, event):
        if event.type in {"RET", "NUMPAD_ENTER", "ESC"} and event.value == "PRESS":
            _status(context, "Draw: finished, %d profiles" % len(core.get_rig(self.obj).profiles))
            return {"FINISHED"}
        if event.type == "Z" and event.ctrl and event.value == "PRESS":
            removed = core.remove_last_profile(self.obj)
            if removed is not None:
                rig = core.get_rig(self.obj)
                last = rig.profiles[len(rig.profiles) - 1] if len(rig.profiles) else None
                self.previous = last.to if last is not None else None
                _status(context, "Draw: removed profile %s" % removed)
            self.stroke = []
            return {"RUNNING_MODAL"}
        if event.type == "MOUSEMOVE" and self.previous is not None:
            hit = core.surface_hit(self.obj, *_event_ray(context, event))
            if hit is not None:
                step = 0.01 * core.state(self.obj).diagonal
                if not self.stroke or ((hit - self.stroke[-1]) ** 2).sum() ** 0.5 > step:
                    self.stroke.append(hit)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "PRESS":
            origin, direction = _event_ray(context, event)
            node = core.add_node_at(self.obj, origin, direction)
            if node is None:
                return {"RUNNING_MODAL"}  # a miss: the click is the user's to make again
            if self.previous is not None and node != self.previous:
                try:
                    rig = core.get_rig(self.obj)
                    ends = [rig.node(self.previous).position, rig.node(node).position]
                    via = [p for p in self.stroke if min(((p - e) ** 2).sum() for e in ends) ** 0.5 > 1e-9]
                    pid = core.add_profile(self.obj, self.previous, node, via or None)
                    _status(context, "Draw: profile %s, %s -> %s" % (pid, self.previous, node))
                except curvenet.Error as e:
                    self.report({"WARNING"}, str(e))
                    _status(context, "Draw: " + str(e))
                    self.stroke = []
                    return {"RUNNING_MODAL"}
            self.previous = node
            self.stroke = []
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}


class CURVENET_OT_connect(_MeshOperator, bpy.types.Operator):
    """Embed the net in the mesh: SUCCESS or FAILED with the counts, and a region preview object"""

    bl_idname = "curvenet.connect"
    bl_label = "Connect"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        ok, _report, message = core.connect(obj)
        _status(context, message)
        failed = core.state(obj).failed_profile
        if failed:
            context.scene.curvenet.selected_profile = failed
        self.report({"INFO"} if ok else {"WARNING"}, "Curvenet embedding: " + message)
        return {"FINISHED"} if ok else {"CANCELLED"}


class CURVENET_OT_starter(_MeshOperator, bpy.types.Operator):
    """Make a starter net from the selected armature's bones (rest pose), for the rigger to edit"""

    bl_idname = "curvenet.starter"
    bl_label = "Starter Net"
    bl_options = {"REGISTER", "UNDO"}

    nodes_per_ring: IntProperty(name="Nodes per ring", default=4, min=3, max=16)

    def execute(self, context):
        obj, arm = _mesh(context), _armature(context)
        if arm is None:
            self.report({"ERROR"}, "Select an armature (or set one in the panel)")
            return {"CANCELLED"}
        ok, r = _attempt(self, context, "Starter", lambda: core.starter(obj, arm, nodes_per_ring=self.nodes_per_ring))
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Starter: %d rings, %d nodes, %d profiles, %d components" % (
            r.rings, len(r.rig.nodes), len(r.rig.profiles), r.net_components))


class CURVENET_OT_make_armature(_MeshOperator, bpy.types.Operator):
    """Make an armature from the rig's skeleton (an imported rig brings one), placed with the mesh"""

    bl_idname = "curvenet.make_armature"
    bl_label = "Make Armature"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        ok, arm = _attempt(self, context, "Make armature", lambda: core.make_armature(_mesh(context)))
        if not ok:
            return {"CANCELLED"}
        context.scene.curvenet.armature = arm
        return _done(self, context, "Armature %s: %d bones" % (arm.name, len(arm.data.bones)))


class CURVENET_OT_bind(_MeshOperator, bpy.types.Operator):
    """Bind the net to the selected armature; the mesh then follows the armature through the net"""

    bl_idname = "curvenet.bind"
    bl_label = "Bind"
    bl_options = {"REGISTER", "UNDO"}

    method: EnumProperty(
        name="Method",
        items=(("SCENE", "Panel's", "The method set in the panel"),
               ("dq", "Dual quaternion", "Blend the joints' rigid motions per vertex as dual quaternions, with the net's weights"),
               ("harmonic", "Harmonic", "Blend the joints' matrices per vertex, linearly, with the net's weights"),
               ("gradient", "Gradient", "Per-face deformation gradients, rotation-aware, and a Poisson solve")),
        default="SCENE")

    def execute(self, context):
        obj, arm = _mesh(context), _armature(context)
        if arm is None:
            self.report({"ERROR"}, "Select an armature (or set one in the panel)")
            return {"CANCELLED"}
        method = context.scene.curvenet.method if self.method == "SCENE" else self.method
        layer = context.scene.curvenet.layer
        ok, b = _attempt(self, context, "Bind", lambda: core.bind(obj, arm, method, layer=layer))
        if not ok:
            return {"CANCELLED"}
        context.scene.curvenet.armature = arm
        return _done(self, context, "Bind (%s%s): %d vertices, %.2f influences per vertex" % (
            b.method, ", over the Armature" if layer else "", b.report["vertices"], b.report["mean_influences"]))


class CURVENET_OT_unbind(_MeshOperator, bpy.types.Operator):
    """Stop deforming the mesh through the net (its rest shape and Armature modifiers come back)"""

    bl_idname = "curvenet.unbind"
    bl_label = "Unbind"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        core.unbind(_mesh(context))
        _status(context, "Unbound")
        return {"FINISHED"}


class CURVENET_OT_pick_node(_MeshOperator, bpy.types.Operator):
    """Click node markers to select them for the weight editor (Shift adds); Enter or Esc finishes"""

    bl_idname = "curvenet.pick_node"
    bl_label = "Pick Nodes"

    def invoke(self, context, event):
        if context.area is None or context.area.type != "VIEW_3D":
            return {"CANCELLED"}
        self.obj = _mesh(context)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        context.area.tag_redraw()
        if event.type in {"RET", "NUMPAD_ENTER", "ESC"} and event.value == "PRESS":
            return {"FINISHED"}
        if event.type == "LEFTMOUSE" and event.value == "PRESS":
            try:
                self._pick(context, event)
            except curvenet.Error as e:
                self.report({"ERROR"}, str(e))
                return {"CANCELLED"}
            return {"RUNNING_MODAL"}
        return {"PASS_THROUGH"}

    def _pick(self, context, event):
        node = core.nearest_node(self.obj, *_event_ray(context, event))
        if node is not None:
            props = context.scene.curvenet
            chosen = [s for s in props.selected_nodes.split(",") if s.strip()] if event.shift else []
            if node not in chosen:
                chosen.append(node)
            props.selected_nodes = ",".join(chosen)
            w = core.node_weights(self.obj, node)
            _status(context, "Node %s: %s" % (node, ", ".join("%s %.2f" % kv for kv in sorted(w.items()))))


class CURVENET_OT_set_node_weight(_MeshOperator, bpy.types.Operator):
    """Set the active bone's weight on the selected nodes (the others are scaled to sum to 1)"""

    bl_idname = "curvenet.set_node_weight"
    bl_label = "Set Node Weight"
    bl_options = {"REGISTER", "UNDO"}

    weight: FloatProperty(name="Weight", default=1.0, min=0.0, max=1.0)
    bone: StringProperty(name="Bone", description="Empty: the armature's active bone")
    nodes: StringProperty(name="Nodes", description="Comma-separated node ids; empty: the selected nodes")

    def execute(self, context):
        obj = _mesh(context)
        props = context.scene.curvenet
        nodes = [s.strip() for s in (self.nodes or props.selected_nodes).split(",") if s.strip()]
        bone = self.bone
        if not bone:
            arm = _armature(context) or core.bound_armature(obj)
            active = arm.data.bones.active if arm is not None else None
            bone = active.name if active is not None else ""
        if not nodes or not bone:
            self.report({"ERROR"}, "Pick nodes and an active bone first")
            return {"CANCELLED"}
        ok, _ = _attempt(self, context, "Set node weight", lambda: core.set_node_weight(obj, nodes, bone, self.weight),
                         (curvenet.Error, KeyError, ValueError))
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Weight of %s set to %.3f on %s" % (bone, self.weight, ", ".join(nodes)))


class CURVENET_OT_transfer(_MeshOperator, bpy.types.Operator):
    """Transfer the net to the selected (or the panel's) target mesh of the same character"""

    bl_idname = "curvenet.transfer"
    bl_label = "Transfer"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        target = _target(context, obj)
        if target is None:
            self.report({"ERROR"}, "Select a target mesh (or set one in the panel)")
            return {"CANCELLED"}
        ok, r = _attempt(self, context, "Transfer", lambda: core.transfer(obj, target))
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Transfer %s to %s: %s, %d regions, %.2f%% of the area agrees" % (
            obj.name, target.name, "SUCCESS" if r.ok else "FAILED", r.report["target"]["regions"], 100 * r.agreement),
            r.ok)


class CURVENET_OT_export_rig(_MeshOperator, bpy.types.Operator, ExportHelper):
    """Write the mesh's net as a rig file"""

    bl_idname = "curvenet.export_rig"
    bl_label = "Export Rig"
    filename_ext = ".cnrig.json"
    filter_glob: StringProperty(default="*.cnrig.json", options={"HIDDEN"})
    up: EnumProperty(name="Space", items=(("Z", "Blender (Z-up)", "The object's own space"),
                                          ("Y", "Y-up file (glTF)", "The space of the glTF file the mesh came from")),
                     default="Z")

    def execute(self, context):
        ok, _ = _attempt(self, context, "Export rig", lambda: core.export_rig(_mesh(context), self.filepath, self.up))
        return _done(self, context, "Rig written: " + self.filepath) if ok else {"CANCELLED"}


class CURVENET_OT_import_rig(_MeshOperator, bpy.types.Operator, ImportHelper):
    """Read a rig file onto the mesh (in its object space)"""

    bl_idname = "curvenet.import_rig"
    bl_label = "Import Rig"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".cnrig.json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})
    up: EnumProperty(name="Space", items=(("AUTO", "Auto", "Whichever puts the nodes nearer the surface"),
                                          ("Z", "Blender (Z-up)", "The rig is in the object's own space"),
                                          ("Y", "Y-up file (glTF)", "The rig was made on the glTF file")),
                     default="AUTO")

    def execute(self, context):
        ok, rig = _attempt(self, context, "Import rig", lambda: core.import_rig(_mesh(context), self.filepath, self.up))
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Rig read: %d nodes, %d profiles" % (len(rig.nodes), len(rig.profiles)))


class CURVENET_OT_bake_cache(_MeshOperator, bpy.types.Operator, ExportHelper):
    """Bake the scene's frame range to a PC2 cache with a Mesh Cache modifier, so the .blend plays without the add-on"""

    bl_idname = "curvenet.bake_cache"
    bl_label = "Bake Cache"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".pc2"
    filter_glob: StringProperty(default="*.pc2", options={"HIDDEN"})
    frame_start: IntProperty(name="Start", default=-1, description="-1: the scene's")
    frame_end: IntProperty(name="End", default=-1, description="-1: the scene's")

    def execute(self, context):
        scene = context.scene
        start = scene.frame_start if self.frame_start < 0 else self.frame_start
        end = scene.frame_end if self.frame_end < 0 else self.frame_end
        path = bpy.path.abspath(self.filepath)
        ok, _ = _attempt(self, context, "Bake cache", lambda: core.bake_cache(_mesh(context), path, start, end, scene),
                         (curvenet.Error, ValueError))
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Cache written: %s (frames %d-%d)" % (os.path.basename(path), start, end))


class CURVENET_OT_bake_vertex_groups(_MeshOperator, bpy.types.Operator):
    """Bake the binding to vertex groups with an Armature modifier: an ordinary skin that plays with stock Blender"""

    bl_idname = "curvenet.bake_vertex_groups"
    bl_label = "Bake to Vertex Groups"
    bl_options = {"REGISTER", "UNDO"}

    max_influences: IntProperty(name="Influences", default=4, min=1, max=8)

    def execute(self, context):
        obj = _mesh(context)
        arm = _armature(context) or core.bound_armature(obj)
        if arm is None:
            self.report({"ERROR"}, "Select an armature (or set one in the panel)")
            return {"CANCELLED"}
        ok, w = _attempt(self, context, "Bake to vertex groups", lambda: core.bake_vertex_groups(obj, arm, self.max_influences))
        if not ok:
            return {"CANCELLED"}
        used = int((w.joint >= 0).sum())
        return _done(self, context, "Vertex groups: %d vertices, %.2f joints each, Armature modifier on %s" % (
            w.num_vertices, used / max(1, w.num_vertices), arm.name))


class CURVENET_OT_clear(_MeshOperator, bpy.types.Operator):
    """Remove the net from the mesh"""

    bl_idname = "curvenet.clear"
    bl_label = "Clear Net"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        core.unbind(obj)
        core.clear_rig(obj)
        _status(context, "Net removed")
        return {"FINISHED"}


CLASSES = (
    CURVENET_OT_draw,
    CURVENET_OT_connect,
    CURVENET_OT_starter,
    CURVENET_OT_make_armature,
    CURVENET_OT_bind,
    CURVENET_OT_unbind,
    CURVENET_OT_pick_node,
    CURVENET_OT_set_node_weight,
    CURVENET_OT_transfer,
    CURVENET_OT_export_rig,
    CURVENET_OT_import_rig,
    CURVENET_OT_bake_cache,
    CURVENET_OT_bake_vertex_groups,
    CURVENET_OT_clear,
)
