"""The add-on as a user installs it: the zip from the build, through
Preferences' Install (addon_install), into a user scripts folder of its own
(BLENDER_USER_SCRIPTS, set by ctest), then enabled and used, with its own
compiled module from inside the zip.

    BLENDER_USER_SCRIPTS=DIR blender -b --factory-startup --python-exit-code 1 --python test_zip_install.py -- BUILD_DIR
"""

import os
import sys

import bpy

build = os.path.abspath(sys.argv[sys.argv.index("--") + 1])
user = os.environ.get("BLENDER_USER_SCRIPTS", "")
if not user:
    raise AssertionError("CURVENET_TEST failed: BLENDER_USER_SCRIPTS is not set")
bpy.ops.wm.read_factory_settings(use_empty=True)
result = bpy.ops.preferences.addon_install(filepath=os.path.join(build, "blender", "curvenet_blender.zip"), overwrite=True)
assert result == {"FINISHED"}, "CURVENET_TEST failed: addon_install " + str(result)
bpy.ops.preferences.addon_enable(module="curvenet_blender")
import curvenet  # noqa: E402
import curvenet_blender  # noqa: E402

installed = os.path.realpath(os.path.dirname(curvenet_blender.__file__))
assert installed.startswith(os.path.realpath(user)), "CURVENET_TEST failed: the add-on came from " + installed
assert os.path.realpath(curvenet.__file__).startswith(installed), (
    "CURVENET_TEST failed: the module came from " + curvenet.__file__)
bpy.ops.mesh.primitive_uv_sphere_add()
sphere = bpy.context.active_object
from curvenet_blender import core  # noqa: E402

nodes = [core.add_node_at(sphere, (0, 0, 0), d) for d in ((1, 0, 0.2), (0, 1, 0.2), (-1, 0, 0.2), (0, -1, 0.2))]
for i in range(4):
    core.add_profile(sphere, nodes[i], nodes[(i + 1) % 4])
assert bpy.ops.curvenet.connect() == {"FINISHED"}, "CURVENET_TEST failed: " + bpy.context.scene.curvenet.status
print("CURVENET_TEST ok: installed from the zip into", installed, "and connected:", bpy.context.scene.curvenet.status)
print("CURVENET_TEST all passed")
