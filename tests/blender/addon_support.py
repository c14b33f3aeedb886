"""What the headless add-on tests share: enabling the add-on from the build
tree, importing the shared data, checks that end Blender with exit code 1,
and Workbench renders.

Run as: blender -b --factory-startup --python-exit-code 1 --python TEST.py -- BUILD_DIR DATA_DIR OUT_DIR
"""

import math
import os
import sys

import bpy
import numpy

numpy.bool = bool  # Blender 3.4's glTF importer uses numpy.bool, which Debian's numpy has removed

ARGS = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
BUILD, DATA, OUT = (os.path.abspath(a) for a in ARGS[:3])
os.makedirs(OUT, exist_ok=True)
if not os.path.isdir(DATA):
    print("CURVENET_TEST skipped: no shared data at " + DATA)
    sys.exit(0)


def enable_addon():
    """Enables curvenet_blender as built in BUILD/blender (the compiled module inside it)."""
    import addon_utils

    path = os.path.join(BUILD, "blender")
    if path not in sys.path:
        sys.path.insert(0, path)
    mod = addon_utils.enable("curvenet_blender", default_set=True, handle_error=None)
    check(mod is not None, "the add-on is enabled")
    import curvenet

    check(os.path.realpath(curvenet.__file__).startswith(os.path.realpath(path)), "the add-on's own module is used")
    return mod


def draw_shell(name):
    """The Draw operator's state and methods without a window, for mesh `name`:
    feed it events with `.ray` (the world-space ray under the mouse) through
    `_step(bpy.context, event)`. Its reports are kept in `.reports`."""
    from curvenet_blender import operators

    operators._event_ray = lambda _context, event: event.ray

    class Shell:
        obj = operators.CURVENET_OT_draw.obj
        _step = operators.CURVENET_OT_draw._step
        _click = operators.CURVENET_OT_draw._click
        _undo = operators.CURVENET_OT_draw._undo

        def __init__(self):
            self.obj_name, self.previous, self.stroke, self.reports = name, None, [], []

        def report(self, kind, text):
            print("REPORT", kind, text)
            self.reports.append((kind, text))

    return Shell()


def check(condition, what):
    if not condition:
        raise AssertionError("CURVENET_TEST failed: " + what)
    print("CURVENET_TEST ok:", what)


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def import_gltf(path):
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=path)
    new = [o for o in bpy.data.objects if o not in before]
    meshes = [o for o in new if o.type == "MESH"]
    arms = [o for o in new if o.type == "ARMATURE"]
    return meshes, arms


def select(active, *others):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    for o in (active,) + others:
        o.select_set(True)
    bpy.context.view_layer.objects.active = active


def evaluated_positions(obj):
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    me = ev.to_mesh()
    co = numpy.empty(len(me.vertices) * 3, dtype=numpy.float32)
    me.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    return co.reshape(-1, 3).astype(numpy.float64)


def render_workbench(objects, path, colour="MATERIAL", size=(800, 600), side=1.0, view=None, up=None):
    """A Workbench still of `objects`: by default the camera looks along their
    thinnest extent (a palm's normal), with the longest one across the
    picture; or from `view` (towards the camera), with `up` up."""
    from mathutils import Matrix, Vector

    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 100
    if scene.world is None:
        scene.world = bpy.data.worlds.new("curvenet_world")
    scene.world.color = (0.82, 0.84, 0.87)
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = colour
    shading.single_color = (0.8, 0.62, 0.5)
    shading.show_cavity = False
    scene.display.render_aa = "8"
    visible = set(objects)
    for o in scene.objects:
        o.hide_render = o not in visible
    bpy.context.view_layer.update()  # bounding boxes of new objects
    pts = numpy.array([(o.matrix_world @ Vector(c))[:] for o in objects for c in o.bound_box])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, extent = (lo + hi) / 2, hi - lo
    order = numpy.argsort(extent)
    axes = numpy.eye(3)
    z = Vector(view if view is not None else side * axes[order[0]] + 0.35 * axes[order[1]]).normalized()
    if up is not None:
        y = Vector(up)
        y = (y - z * y.dot(z)).normalized()
        x = y.cross(z)
    else:
        x = Vector(axes[order[2]])
        x = (x - z * x.dot(z)).normalized()
        y = z.cross(x)
    cam_data = bpy.data.cameras.new("curvenet_camera")
    cam_data.lens = 50
    cam = bpy.data.objects.new("curvenet_camera", cam_data)
    scene.collection.objects.link(cam)
    radius = numpy.linalg.norm(extent) / 2
    distance = radius / math.tan(cam_data.angle / 2) * 1.05
    cam.matrix_world = Matrix.Translation(Vector(centre) + z * distance) @ Matrix(
        [[x[0], y[0], z[0], 0], [x[1], y[1], z[1], 0], [x[2], y[2], z[2], 0], [0, 0, 0, 1]]
    )
    cam_data.clip_start = distance / 100
    cam_data.clip_end = distance * 10
    scene.camera = cam
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    bpy.data.objects.remove(cam)
    bpy.data.cameras.remove(cam_data)
    img = bpy.data.images.load(path)
    px = numpy.array(img.pixels[:]).reshape(-1, 4)[:, :3]
    spread = float(px.std(axis=0).max())
    bpy.data.images.remove(img)
    check(os.path.getsize(path) > 10000 and spread > 0.02, "the render %s shows something" % os.path.basename(path))
    return path
