"""The sidebar panel (3D view, N panel, tab "Curvenet"): the thesis's workflow, top to bottom."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty, StringProperty

from . import core


def _is_armature(_self, obj):
    return obj.type == "ARMATURE"


def _is_mesh(_self, obj):
    return obj.type == "MESH"


class CurvenetSceneProps(bpy.types.PropertyGroup):
    armature: PointerProperty(name="Armature", type=bpy.types.Object, poll=_is_armature)
    target: PointerProperty(name="Target", type=bpy.types.Object, poll=_is_mesh)
    selected_nodes: StringProperty(name="Nodes", description="Nodes for the weight editor, comma-separated")
    selected_profile: StringProperty(name="Profile", description="The profile the last failure named")
    weight: FloatProperty(name="Weight", default=1.0, min=0.0, max=1.0)
    method: EnumProperty(
        name="Method",
        items=(("dq", "Dual quaternion", "Blend the joints' rigid motions per vertex as dual quaternions, with the net's weights"),
               ("harmonic", "Harmonic", "Blend the joints' matrices per vertex, linearly, with the net's weights"),
               ("gradient", "Gradient", "Per-face deformation gradients, rotation-aware, and a Poisson solve")),
        default="dq")
    layer: BoolProperty(
        name="Layer over Armature",
        description="Keep the mesh's Armature modifier (its skin, Preserve Volume or not) and layer the net over it "
                    "as a corrective shape key",
        default=False)
    status: StringProperty(name="Status")


class CURVENET_PT_panel(bpy.types.Panel):
    bl_label = "Curvenet"
    bl_idname = "CURVENET_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Curvenet"

    def draw(self, context):
        layout = self.layout
        props = context.scene.curvenet
        obj = context.active_object
        if obj is None or obj.type != "MESH":
            layout.label(text="Select a mesh")
            return
        rig = core.get_rig(obj) if core.has_rig(obj) else None
        box = layout.box()
        box.label(text="1. Net", icon="CURVE_DATA")
        row = box.row(align=True)
        row.operator("curvenet.draw")
        row.operator("curvenet.starter")
        if rig is not None:
            box.label(text="%d nodes, %d profiles" % (len(rig.nodes), len(rig.profiles)))
        row = box.row(align=True)
        row.operator("curvenet.import_rig", text="Import")
        row.operator("curvenet.export_rig", text="Export")
        row.operator("curvenet.clear", text="", icon="X")

        box = layout.box()
        box.label(text="2. Connect", icon="MOD_MESHDEFORM")
        box.operator("curvenet.connect")
        rep = core.state(obj).report
        if rep is not None:
            col = box.column(align=True)
            col.label(text="SUCCESS" if rep["ok"] else "FAILED", icon="CHECKMARK" if rep["ok"] else "ERROR")
            col.label(text="regions %d / expected %s" % (rep["regions"], rep["expected_regions"]))
            col.label(text="unmapped faces %d" % rep["unmapped_faces"])
        if props.selected_profile:
            box.label(text="profile: " + props.selected_profile, icon="ERROR")

        box = layout.box()
        box.label(text="3. Bind", icon="ARMATURE_DATA")
        box.prop(props, "armature")
        box.prop(props, "method")
        box.prop(props, "layer")
        if rig is not None and rig.has_skeleton and props.armature is None:
            box.operator("curvenet.make_armature")
        row = box.row(align=True)
        row.operator("curvenet.bind")
        row.operator("curvenet.unbind")
        box.label(text="Node weights")
        row = box.row(align=True)
        row.operator("curvenet.pick_node", text="Pick")
        row.prop(props, "selected_nodes", text="")
        arm = props.armature or core.bound_armature(obj)
        if arm is not None and arm.data.bones.active is not None:
            box.label(text="bone: " + arm.data.bones.active.name, icon="BONE_DATA")
        row = box.row(align=True)
        row.prop(props, "weight")
        op = row.operator("curvenet.set_node_weight", text="Set")
        op.weight = props.weight

        box = layout.box()
        box.label(text="4. Transfer and bake", icon="EXPORT")
        box.prop(props, "target")
        box.operator("curvenet.transfer")
        box.operator("curvenet.bake_cache")
        box.operator("curvenet.bake_vertex_groups")
        if props.status:
            layout.label(text=props.status)
        err = core.state(obj).error
        if err:
            layout.label(text=err, icon="ERROR")


CLASSES = (CurvenetSceneProps, CURVENET_PT_panel)


def register():
    bpy.types.Scene.curvenet = PointerProperty(type=CurvenetSceneProps)


def unregister():
    if hasattr(bpy.types.Scene, "curvenet"):
        del bpy.types.Scene.curvenet
