"""Curvenet for Blender: draw a curve network on a character, connect it,
bind it to an armature, tune node weights, transfer it to other meshes of
the character, and bake a point cache. See docs/blender.md."""

bl_info = {
    "name": "Curvenet",
    "author": "The curvenet developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D View > Sidebar > Curvenet",
    "description": "Topology-independent character deformation with curve networks",
    "category": "Rigging",
}

import os
import sys

# The compiled module: installed for this Python, or shipped inside the add-on.
try:
    import curvenet  # noqa: F401
except ImportError:
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "_vendor"))
    import curvenet  # noqa: F401

import bpy

from . import core, draw, edit, edit_tool, live, operators, ui  # noqa: F401


def register():
    for cls in ui.CLASSES + operators.CLASSES + edit_tool.CLASSES:
        bpy.utils.register_class(cls)
    ui.register()
    live.register()
    draw.register()


def unregister():
    draw.unregister()
    live.unregister()
    ui.unregister()
    for cls in reversed(ui.CLASSES + operators.CLASSES + edit_tool.CLASSES):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
