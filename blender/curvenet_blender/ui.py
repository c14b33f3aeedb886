"""The sidebar panel (3D view, N panel, tab "Curvenet"): the thesis's workflow, top to bottom."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty, StringProperty

from . import core, operators


def _is_armature(_self, obj):
    return obj.type == "ARMATURE"


def _is_mesh(_self, obj):
    return obj.type == "MESH"


class CurvenetSceneProps(bpy.types.PropertyGroup):
    armature: PointerProperty(name="Armature", type=bpy.types.Object, poll=_is_armature)
    target: PointerProperty(name="Target", type=bpy.types.Object, poll=_is_mesh)
    selected_nodes: StringProperty(name="Nodes", description="The selected nodes, comma-separated")
    selected_profiles: StringProperty(name="Profiles", description="The selected profiles, comma-separated")
    snap: FloatProperty(
        name="Snap", default=core.SNAP_FRACTION, min=0.001, max=0.2, precision=3,
        description="A click this near a node (a fraction of the mesh's diagonal, never more than a third of "
                    "the limb's thickness there) reuses the node")
    selected_profile: StringProperty(name="Profile", description="The profile the last failure named")
    weight: FloatProperty(name="Weight", default=1.0, min=0.0, max=1.0)
    method: EnumProperty(
        name="Method",
        items=(("dq", "DQ", "Dual quaternion: blend the joints' rigid motions per vertex as dual quaternions, with the net's weights"),
               ("harmonic", "Harmonic", "Blend the joints' matrices per vertex, linearly, with the net's weights"),
               ("gradient", "Gradient", "Per-face deformation gradients, rotation-aware, and a Poisson solve")),
        default="dq")
    layer: BoolProperty(
        name="Layer over Armature",
        description="Keep the mesh's Armature modifier (its skin, Preserve Volume or not) and layer the net over it "
                    "as a corrective shape key",
        default=False)
    status: StringProperty(name="Status")
    show_starter_notes: BoolProperty(name="Reasons", description="Show why each joint has no ring", default=True)


class CURVENET_PT_panel(bpy.types.Panel):
    bl_label = "Curvenet"
    bl_idname = "CURVENET_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Curvenet"

    def draw(self, context):
        layout = self.layout
        props = context.scene.curvenet
        obj = operators._mesh(context)
        if obj is None:
            layout.label(text="Select a mesh (and its armature)")
            return
        rig = core.get_rig(obj) if core.has_rig(obj) else None
        box = layout.box()
        box.label(text="1. Net", icon="CURVE_DATA")
        row = box.row(align=True)
        row.operator("curvenet.draw")
        row.operator("curvenet.starter", text="Starter")
        row = box.row(align=True)
        row.prop(props, "snap")
        if rig is not None:
            box.label(text="%d nodes, %d profiles" % (len(rig.nodes), len(rig.profiles)))
            row = box.row(align=True)
            row.operator("curvenet.edit_net", icon="EDITMODE_HLT")
            row.operator("curvenet.delete", text="", icon="TRASH")
            row.operator("curvenet.merge_nodes", text="", icon="AUTOMERGE_ON")
            if props.selected_nodes or props.selected_profiles:
                col = box.column(align=True)
                if props.selected_nodes:
                    col.label(text="nodes: " + props.selected_nodes, icon="DOT")
                if props.selected_profiles:
                    col.label(text="profiles: " + props.selected_profiles, icon="IPO_LINEAR")
        notes = core.starter_notes(obj)
        if notes:
            sub = box.box()
            row = sub.row()
            row.prop(props, "show_starter_notes", text="%d joints without a ring" % len(notes), emboss=False,
                     icon="TRIA_DOWN" if props.show_starter_notes else "TRIA_RIGHT")
            for joint, reason in notes[:12]:
                col = sub.column(align=True)
                op = col.operator("curvenet.select_bone", text=joint, emboss=False, icon="BONE_DATA")
                op.bone = joint
                if props.show_starter_notes:
                    for line in _wrap(reason, 28):
                        col.label(text="    " + line)
            if len(notes) > 12:
                sub.label(text="and %d more" % (len(notes) - 12))
        row = box.row(align=True)
        row.operator("curvenet.import_rig", text="Import")
        row.operator("curvenet.export_rig", text="Export")
        row.operator("curvenet.clear", text="", icon="X")

        box = layout.box()
        box.label(text="2. Connect", icon="MOD_MESHDEFORM")
        box.operator("curvenet.connect")
        result = core.connect_result(obj)
        if result is not None:
            col = box.column(align=True)
            col.label(text="SUCCESS" if result["ok"] else "FAILED", icon="CHECKMARK" if result["ok"] else "ERROR")
            rep = result["report"]
            if rep is not None:
                col.label(text="regions %d / expected %s" % (rep["regions"], rep["expected_regions"]))
                col.label(text="unmapped faces %d" % rep["unmapped_faces"])
            if result.get("failed_profile"):
                col.label(text="profile: " + result["failed_profile"], icon="ERROR")
        elif rig is not None and obj.get(core.CONNECT_KEY):
            box.label(text="the net changed since: connect again", icon="INFO")

        box = layout.box()
        box.label(text="3. Bind", icon="ARMATURE_DATA")
        col = box.column()
        col.use_property_split = True
        col.prop(props, "armature", text="Rig")
        col.prop(props, "method", text="Mode")
        col.prop(props, "layer", text="Layer")
        if rig is not None and rig.has_skeleton and props.armature is None and core.matching_armature(obj) is None:
            box.operator("curvenet.make_armature")
        row = box.row(align=True)
        row.operator("curvenet.bind")
        row.operator("curvenet.unbind")
        playing = _wrap("Playing: " + core.describe_deformation(obj), 26)
        for i, line in enumerate(playing):
            box.label(text=line, icon="PLAY" if i == 0 else "BLANK1")
        key = core.layer_key(obj)
        if key is not None:  # the layer's envelope (keyable) and mask: the shape key's own
            col = box.column()
            col.use_property_split = True
            col.prop(key, "value", text="Envelope")
            col.prop_search(key, "vertex_group", obj, "vertex_groups", text="Mask")
        box.label(text="Node weights")
        row = box.row(align=True)
        row.operator("curvenet.pick_node", text="Pick")
        row.prop(props, "selected_nodes", text="")
        row.operator("curvenet.pull_node", text="Pull")
        arm = props.armature or core.bound_armature(obj)
        if arm is not None and arm.data.bones.active is not None:
            box.label(text="bone: " + arm.data.bones.active.name, icon="BONE_DATA")
        row = box.row(align=True)
        row.prop(props, "weight", text="")
        op = row.operator("curvenet.set_node_weight", text="Set weight")
        op.weight = props.weight

        box = layout.box()
        box.label(text="4. Transfer and bake", icon="EXPORT")
        box.prop(props, "target")
        box.operator("curvenet.transfer")
        box.operator("curvenet.bake_cache")
        box.operator("curvenet.bake_vertex_groups")
        if props.status:
            for line in _wrap(props.status, 30):
                layout.label(text=line)
        err = core.state(obj).error
        if err:
            layout.label(text=err, icon="ERROR")


def _wrap(text, width):
    """The status on several lines: a sidebar label cuts a long line off."""
    words, lines, line = text.split(), [], ""
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            lines.append(line)
            line = w
        else:
            line = (line + " " + w).strip()
    if line:
        lines.append(line)
    return lines[:8]


class CURVENET_OT_select_bone(bpy.types.Operator):
    """Make the bone the armature's active, selected bone (to see where a ring is missing)"""

    bl_idname = "curvenet.select_bone"
    bl_label = "Select Bone"
    bl_options = {"REGISTER", "UNDO"}

    bone: StringProperty(name="Bone")

    def execute(self, context):
        obj = operators._mesh(context)
        arm = context.scene.curvenet.armature or (core.bound_armature(obj) if obj is not None else None)
        if arm is None or self.bone not in arm.data.bones:
            self.report({"ERROR"}, "No armature with a bone %s: set the armature in the panel" % self.bone)
            return {"CANCELLED"}
        for b in arm.data.bones:
            b.select = b.select_head = b.select_tail = False
        bone = arm.data.bones[self.bone]
        bone.select = bone.select_head = bone.select_tail = True
        arm.data.bones.active = bone
        self.report({"INFO"}, "Bone %s selected" % self.bone)
        return {"FINISHED"}


CLASSES = (CurvenetSceneProps, CURVENET_PT_panel, CURVENET_OT_select_bone)


def header(self, context):
    """While Draw or Edit Net runs, the 3D view's header shows the snap setting, to adjust as one draws."""
    if operators.RUNNING and getattr(context.scene, "curvenet", None) is not None:
        self.layout.separator()
        self.layout.label(text="Curvenet " + " / ".join(sorted(operators.RUNNING)), icon="CURVE_DATA")
        self.layout.prop(context.scene.curvenet, "snap")


def register():
    bpy.types.Scene.curvenet = PointerProperty(type=CurvenetSceneProps)
    bpy.types.VIEW3D_HT_header.append(header)


def unregister():
    bpy.types.VIEW3D_HT_header.remove(header)
    if hasattr(bpy.types.Scene, "curvenet"):
        del bpy.types.Scene.curvenet
