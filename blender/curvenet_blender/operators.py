"""The workflow's steps as operators: thin shells over core.py, so every
step can be scripted (bpy.ops.curvenet.*) and tested headless."""

import os

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras import view3d_utils
from bpy_extras.io_utils import ExportHelper, ImportHelper

import curvenet

from . import core


def _is_character_mesh(o):
    return o is not None and o.type == "MESH" and not o.get("curvenet_preview_of")


def _mesh(context):
    """The mesh to work on: the active object, or, with an armature active
    (selected last, as for Ctrl+P), the selected mesh."""
    obj = context.active_object
    if _is_character_mesh(obj):
        return obj
    if obj is not None and obj.type == "ARMATURE":
        meshes = [o for o in context.selected_objects if _is_character_mesh(o)]
        if len(meshes) == 1:
            return meshes[0]
    return None


def _armature(context):
    """The armature: the active one, a selected one, the panel's, or the one the mesh is bound to."""
    obj = context.active_object
    if obj is not None and obj.type == "ARMATURE":
        return obj
    for o in context.selected_objects:
        if o.type == "ARMATURE":
            return o
    mesh = _mesh(context)
    return context.scene.curvenet.armature or (core.bound_armature(mesh) if mesh is not None else None)


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


def redraw(context):
    """Every 3D view and the panel show the change at once."""
    screen = context.screen
    for area in screen.areas if screen is not None else ():
        if area.type == "VIEW_3D":
            area.tag_redraw()


def _message(e):
    """An exception as one sentence: a KeyError's text without its quotes."""
    text = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
    text = str(text).strip()
    return (text[:1].upper() + text[1:]) if text else type(e).__name__


def _attempt(op, context, label, call, errors=(curvenet.Error, KeyError, ValueError)):
    """Runs a core call; a refusal is reported in the info bar and the panel.
    Returns (ok, result)."""
    try:
        return True, call()
    except errors as e:
        op.report({"ERROR"}, _message(e))
        _status(context, "%s: %s" % (label, _message(e)))
        redraw(context)
        return False, None


def _done(op, context, message, ok=True):
    _status(context, message)
    op.report({"INFO"} if ok else {"WARNING"}, message)
    redraw(context)
    return {"FINISHED"} if ok else {"CANCELLED"}


class _MeshOperator:
    @classmethod
    def poll(cls, context):
        return _mesh(context) is not None


DRAW_HINT = ("Draw: click on the mesh to place nodes (a click near a node reuses it); each click after the first "
             "makes a profile | [ ] snap radius | Ctrl+Z undo | Enter/Esc finish")

RUNNING = set()  # the modal tools running now: the 3D view's header shows their snap setting


def show_hint(context, name, text):
    """The tool's keys in the status bar, and its snap setting in the 3D view's header."""
    RUNNING.add(name)
    if context.workspace is not None:
        context.workspace.status_text_set(text)
    redraw(context)


def hide_hint(context, name):
    RUNNING.discard(name)
    if context.workspace is not None:
        context.workspace.status_text_set(None)
    redraw(context)


def change_snap(context, event):
    """[ and ] shrink and grow the snap radius. Returns True when the event was one."""
    if event.type not in {"LEFT_BRACKET", "RIGHT_BRACKET"} or event.value != "PRESS":
        return False
    props = context.scene.curvenet
    props.snap = props.snap * (0.8 if event.type == "LEFT_BRACKET" else 1.25)
    _status(context, "Snap: %.3f of the diagonal (at most a third of the limb's thickness)" % props.snap)
    return True


class CURVENET_OT_draw(_MeshOperator, bpy.types.Operator):
    """Draw a net on the mesh: click to place nodes (a click near a node reuses it);
    each click after the first makes a profile, traced on the surface, as one undo
    step. Ctrl+Z undoes a profile; Enter or Esc finishes"""

    bl_idname = "curvenet.draw"
    bl_label = "Draw"
    bl_options = {"REGISTER"}

    @property
    def obj(self):
        return bpy.data.objects.get(self.obj_name)  # looked up anew: an undo replaces the object

    def invoke(self, context, event):
        if context.area is None or context.area.type != "VIEW_3D":
            self.report({"WARNING"}, "Draw works in a 3D view")
            return {"CANCELLED"}
        self.obj_name = _mesh(context).name
        self.previous = None  # the stroke's last end: a node id, or a point not yet a node
        self.stroke = []  # surface points the mouse passed over since the last click
        context.window_manager.modal_handler_add(self)
        show_hint(context, "draw", DRAW_HINT)
        _status(context, DRAW_HINT)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        context.area.tag_redraw()
        try:
            result = self._step(context, event)
        except curvenet.Error as e:  # a mesh the engine refuses: say why and stop
            self.report({"ERROR"}, _message(e))
            _status(context, "Draw: " + _message(e))
            result = {"CANCELLED"}
        if result != {"RUNNING_MODAL"} and result != {"PASS_THROUGH"}:
            hide_hint(context, "draw")
        return result

    def _step(self, context, event):
        obj = self.obj
        if obj is None:
            return {"CANCELLED"}
        if event.type in {"RET", "NUMPAD_ENTER", "ESC"} and event.value == "PRESS":
            _status(context, "Draw: finished, %d profiles" % len(core.get_rig(obj).profiles))
            return {"FINISHED"}
        if event.type == "Z" and event.ctrl and event.value == "PRESS":
            return self._undo(context, redo=event.shift)
        if change_snap(context, event):
            return {"RUNNING_MODAL"}
        if event.type == "MOUSEMOVE" and self.previous is not None:
            hit = core.surface_hit(obj, *_event_ray(context, event))
            if hit is not None:
                step = 0.01 * core.state(obj).diagonal
                if not self.stroke or ((hit - self.stroke[-1]) ** 2).sum() ** 0.5 > step:
                    self.stroke.append(hit)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "PRESS":
            return self._click(context, obj, *_event_ray(context, event))
        return {"PASS_THROUGH"}

    def _click(self, context, obj, origin, direction):
        placed = core.place(obj, origin, direction, context.scene.curvenet.snap)
        if placed is None:
            self.report({"WARNING"}, "Draw: the click missed the mesh")
            _status(context, "Draw: the click missed the mesh; click on its surface")
            return {"RUNNING_MODAL"}
        point, node, radius = placed
        end = node if node is not None else point
        where = "node %s" % node if node is not None else "a new node"
        if self.previous is None or (node is not None and node == self.previous):
            self.previous, self.stroke = end, []
            _status(context, "Draw: starts at %s (snap radius %.3g)" % (where, radius))
            return {"RUNNING_MODAL"}
        ends = [np.asarray(core.get_rig(obj).node(e).position) if isinstance(e, str) else e
                for e in (self.previous, end)]
        via = [p for p in self.stroke if min(((p - e) ** 2).sum() for e in ends) ** 0.5 > 1e-9]
        try:
            pid, a, b = core.add_stroke(obj, self.previous, end, via or None)
        except curvenet.Error as e:
            self.report({"WARNING"}, _message(e))
            _status(context, "Draw: " + _message(e))
            self.stroke = []
            return {"RUNNING_MODAL"}
        bpy.ops.ed.undo_push(message="Curvenet: draw profile %s" % pid)
        _status(context, "Draw: profile %s, %s -> %s (%s)" % (pid, a, b, where))
        self.previous, self.stroke = b, []
        return {"RUNNING_MODAL"}

    def _undo(self, context, redo=False):
        """Blender's own undo (or redo): the profile drawn last goes (or comes back)."""
        try:
            bpy.ops.ed.redo() if redo else bpy.ops.ed.undo()
        except RuntimeError as e:
            _status(context, "Draw: %s" % _message(e))
            return {"RUNNING_MODAL"}
        obj = self.obj
        rig = core.get_rig(obj) if obj is not None else None
        last = rig.profiles[len(rig.profiles) - 1] if rig is not None and len(rig.profiles) else None
        self.previous, self.stroke = (last.to if last is not None else None), []
        _status(context, "Draw: %s, %d profiles" % ("redone" if redo else "undone", len(rig.profiles) if rig else 0))
        return {"RUNNING_MODAL"}


class CURVENET_OT_connect(_MeshOperator, bpy.types.Operator):
    """Embed the net in the mesh: SUCCESS or FAILED with the counts, and a region preview object"""

    bl_idname = "curvenet.connect"
    bl_label = "Connect"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        ok, result = _attempt(self, context, "Connect", lambda: core.connect(obj))
        if not ok:
            return {"CANCELLED"}
        ok, _report, message = result
        failed = (core.connect_result(obj) or {}).get("failed_profile", "")
        context.scene.curvenet.selected_profile = failed
        return _done(self, context, message, ok)


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
        context.scene.curvenet.armature = arm
        return _done(self, context, "Starter: %d rings, %d nodes, %d profiles, %d components; %d joints without a ring" % (
            r.rings, len(r.rig.nodes), len(r.rig.profiles), r.net_components, len(r.ringless)))


class CURVENET_OT_make_armature(_MeshOperator, bpy.types.Operator):
    """Make an armature from the rig's skeleton (an imported rig brings one), placed with the mesh"""

    bl_idname = "curvenet.make_armature"
    bl_label = "Make Armature"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        existing = core.matching_armature(obj)
        ok, arm = _attempt(self, context, "Make armature", lambda: core.make_armature(obj))
        if not ok:
            return {"CANCELLED"}
        context.scene.curvenet.armature = arm
        verb = "Found the armature" if existing is not None else "Made the armature"
        return _done(self, context, "%s %s: %d bones" % (verb, arm.name, len(arm.data.bones)))


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
        return _done(self, context, "Bind (%s): %d vertices, %.2f influences per vertex; playing: %s" % (
            b.method, b.report["vertices"], b.report["mean_influences"], core.describe_deformation(obj)))


class CURVENET_OT_unbind(_MeshOperator, bpy.types.Operator):
    """Stop deforming the mesh through the net (its rest shape and Armature modifiers come back)"""

    bl_idname = "curvenet.unbind"
    bl_label = "Unbind"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        core.unbind(obj)
        return _done(self, context, "Unbound; playing: " + core.describe_deformation(obj))


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


class CURVENET_OT_pull_node(_MeshOperator, bpy.types.Operator):
    """Add a handle to each selected node: an empty on the node's bone; move it, or key its location, to pull the node"""

    bl_idname = "curvenet.pull_node"
    bl_label = "Pull"
    bl_options = {"REGISTER", "UNDO"}

    nodes: StringProperty(name="Nodes", description="Comma-separated node ids; empty: the selected nodes")

    def execute(self, context):
        obj = _mesh(context)
        props = context.scene.curvenet
        nodes = [s.strip() for s in (self.nodes or props.selected_nodes).split(",") if s.strip()]
        if not nodes:
            self.report({"ERROR"}, "Pick nodes first")
            return {"CANCELLED"}
        ok, handles = _attempt(self, context, "Pull", lambda: [core.add_node_handle(obj, n) for n in nodes])
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Handles %s: select one and move it (G), or key its location (I)" % (
            ", ".join(e.name for e in handles)))


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
    """Bake the clip's frames to a PC2 cache with a Mesh Cache modifier, so the .blend plays without the add-on"""

    bl_idname = "curvenet.bake_cache"
    bl_label = "Bake Cache"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".pc2"
    filter_glob: StringProperty(default="*.pc2", options={"HIDDEN"})
    frame_start: IntProperty(name="Start", default=-1, description="-1: the clip's first frame (else the scene's)")
    frame_end: IntProperty(name="End", default=-1, description="-1: the clip's last frame (else the scene's)")

    def invoke(self, context, event):
        obj = _mesh(context)
        start, end = core.clip_range(obj, context.scene)
        if self.frame_start < 0:
            self.frame_start = start
        if self.frame_end < 0:
            self.frame_end = end
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        obj = _mesh(context)
        start = None if self.frame_start < 0 else self.frame_start
        end = None if self.frame_end < 0 else self.frame_end
        path = bpy.path.abspath(self.filepath) if self.filepath else ""
        ok, frames = _attempt(self, context, "Bake cache", lambda: core.bake_cache(obj, path, start, end, context.scene))
        if not ok:
            return {"CANCELLED"}
        return _done(self, context, "Cache written: %s (frames %d-%d); playing: %s" % (
            os.path.basename(path), frames[0], frames[1], core.describe_deformation(obj)))


class CURVENET_OT_bake_vertex_groups(_MeshOperator, bpy.types.Operator):
    """Bake the binding to vertex groups with an Armature modifier: an ordinary skin that plays with stock Blender"""

    bl_idname = "curvenet.bake_vertex_groups"
    bl_label = "Bake to Vertex Groups"
    bl_options = {"REGISTER", "UNDO"}

    max_influences: IntProperty(name="Influences", default=4, min=1, max=8)
    weights: EnumProperty(
        name="Weights",
        items=(("HARMONIC", "Harmonic", "Each vertex's largest weights of the net's own blend"),
               ("FITTED", "Fitted", "Weights fitted to follow the net's deformation as each bone bends and twists: "
                                    "closer than Harmonic when the bind Mode is Harmonic, about the same with DQ")),
        default="HARMONIC")
    helpers: IntProperty(
        name="Helper Bones", default=0, min=0, max=1000,
        description="Fitted only: up to this many helper bones, each half way between two bones (an Armature "
                    "constraint on the two with Preserve Volume), where they bring the skin closest to the net: "
                    "a knee or ankle bent far keeps its shape")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "max_influences")
        layout.prop(self, "weights")
        row = layout.row()
        row.enabled = self.weights == "FITTED"  # helpers are fitted with the weights
        row.prop(self, "helpers")

    def execute(self, context):
        obj = _mesh(context)
        arm = _armature(context) or core.bound_armature(obj)
        if arm is None:
            self.report({"ERROR"}, "Select an armature (or set one in the panel)")
            return {"CANCELLED"}
        ok, w = _attempt(self, context, "Bake to vertex groups",
                         lambda: core.bake_vertex_groups(obj, arm, self.max_influences, self.weights == "FITTED",
                                                         self.helpers))
        if not ok:
            return {"CANCELLED"}
        used = int((w.joint >= 0).sum())
        extra = ", %d helper bones" % len(w.helpers) if w.helpers else ""
        return _done(self, context, "Vertex groups (%s weights%s): %d vertices, %.2f joints each; playing: %s" % (
            self.weights.lower(), extra, w.num_vertices, used / max(1, w.num_vertices),
            core.describe_deformation(obj)))


class CURVENET_OT_clear(_MeshOperator, bpy.types.Operator):
    """Remove the net from the mesh"""

    bl_idname = "curvenet.clear"
    bl_label = "Clear Net"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _mesh(context)
        core.unbind(obj)
        core.clear_rig(obj)
        return _done(self, context, "Net removed; playing: " + core.describe_deformation(obj))


CLASSES = (
    CURVENET_OT_draw,
    CURVENET_OT_connect,
    CURVENET_OT_starter,
    CURVENET_OT_make_armature,
    CURVENET_OT_bind,
    CURVENET_OT_unbind,
    CURVENET_OT_pick_node,
    CURVENET_OT_set_node_weight,
    CURVENET_OT_pull_node,
    CURVENET_OT_transfer,
    CURVENET_OT_export_rig,
    CURVENET_OT_import_rig,
    CURVENET_OT_bake_cache,
    CURVENET_OT_bake_vertex_groups,
    CURVENET_OT_clear,
)
