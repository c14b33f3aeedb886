"""The add-on's non-modal core: every step of the workflow as a function of
Blender objects, with no operator, no event and no UI. The operators
(operators.py) are thin shells over these, and the tests call them directly.

Where things live:
- The rig is the object's custom property ``curvenet_rig`` (rig-file JSON,
  the mesh's object space), so it is saved in the .blend and exports as a
  ``.cnrig.json`` unchanged.
- The armature a mesh is bound to is the object's ``curvenet_armature``, a
  pointer to the armature object (so a rename keeps it), and the deformation
  that plays is ``curvenet_deformation`` (one of DEFORMATIONS).
- The last Connect's result is ``curvenet_connect``, with the rig it was
  made for: undo and redo bring back the rig and its result together.
- Bindings, engine meshes and traced paths are runtime caches (``STATE``),
  each kept with what it was made from (the rig's text, a profile's curve),
  so an undo, a redo or a file load rebuilds them on demand.
- Deformed positions go to a shape key ``curvenet`` on top of the basis:
  the user's rest mesh is never edited.
"""

import hashlib
import json
import math
import os

import bpy
import numpy as np
from mathutils import Matrix, Vector
from mathutils.bvhtree import BVHTree

import curvenet

RIG_KEY = "curvenet_rig"
ARMATURE_KEY = "curvenet_armature"
SHAPE_KEY = "curvenet"
MODIFIERS_KEY = "curvenet_disabled_modifiers"  # the Armature modifiers switched off while bound
PREVIEW_SUFFIX = ".curvenet_regions"
PREVIEW_LIFT = 5e-4  # the preview lies this far outside the mesh (a fraction of the diagonal)
CHAINS_SUFFIX = ".curvenet_chains"
CONNECT_KEY = "curvenet_connect"  # the last Connect's result, with the rig it was made for
STARTER_KEY = "curvenet_starter"  # the last starter net's joints without a ring, and why
DEFORMATION_KEY = "curvenet_deformation"
# A click this close to an existing node (a fraction of the mesh's bounding-box
# diagonal) reuses that node; never more than a third of the limb's local
# thickness (snap_radius).
SNAP_FRACTION = 0.02


class Refused(curvenet.Error):
    """An add-on step that cannot be done, with the sentence that says why."""


class ObjectState:
    """What the add-on keeps for one mesh object while Blender runs."""

    def __init__(self):
        self.mesh_key = None  # what the engine mesh and BVH were built from
        self.mesh = None  # curvenet.Mesh of the rest positions, Blender's vertex order
        self.bvh = None
        self.diagonal = 1.0
        self.paths = {}  # profile id -> (signature of its curve and ends, (k, 3) traced path, object space)
        self.binding = None
        self.binding_for = None  # what the binding was made from (binding_source)
        self.layer = None  # curvenet.CurveLayer when the net is layered over the Armature modifier
        self.rest = None  # (n, 3) rest positions, for the layer's corrective shape key
        self.net_layer = None  # curvenet.CurveLayer over the net itself, for pulled nodes without a skin
        self.bone_names = []  # per binding joint, the armature bone that drives it
        self.node_rest = {}  # node id -> (3,) rest position in the bound rig (read per frame by node_offsets)
        self.matrices = None  # (J, 4, 4) scratch, filled per frame
        self.positions = None  # (n, 3) float32 scratch
        self.last_pose = None  # the matrices of the last update, to skip unchanged poses
        self.changed = None  # scratch for comparing them
        self.error = ""  # the last failure of live deformation, one line
        self.preview = None  # while a node is dragged: {"paths": {id: path}, "nodes": {id: point}}


STATE = {}


def state(obj):
    return STATE.setdefault(obj.name_full, ObjectState())


def forget(obj):
    STATE.pop(obj.name_full, None)


# --- the mesh ---------------------------------------------------------------


def rest_arrays(obj):
    """The rest positions (n, 3) and polygons of a mesh object, in object space."""
    me = obj.data
    n = len(me.vertices)
    co = np.empty(n * 3, dtype=np.float64)
    me.vertices.foreach_get("co", co)  # the basis: shape keys do not change it
    if me.shape_keys and me.shape_keys.reference_key:
        me.shape_keys.reference_key.data.foreach_get("co", co)
    loops = np.empty(len(me.loops), dtype=np.int64)
    me.loops.foreach_get("vertex_index", loops)
    starts = np.empty(len(me.polygons), dtype=np.int64)
    totals = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("loop_start", starts)
    me.polygons.foreach_get("loop_total", totals)
    polygons = [loops[s : s + t].tolist() for s, t in zip(starts, totals)]
    return co.reshape(n, 3), polygons


def engine_mesh(obj):
    """The curvenet.Mesh of the object's rest surface (cached while the mesh is unchanged)."""
    st = state(obj)
    V, polygons = rest_arrays(obj)
    key = (len(V), len(polygons), hash(V.tobytes()))
    if st.mesh_key != key:
        st.mesh = curvenet.Mesh(V, polygons, source=obj.name)
        st.bvh = BVHTree.FromPolygons([Vector(v) for v in V], polygons)
        st.diagonal = st.mesh.bbox_diagonal()
        st.mesh_key = key
    return st.mesh


def surface_bvh(obj):
    engine_mesh(obj)
    return state(obj).bvh


# --- the rig on the object --------------------------------------------------


def has_rig(obj):
    return obj is not None and obj.type == "MESH" and RIG_KEY in obj


def get_rig(obj):
    """The object's rig (a new, empty local one when it has none)."""
    if has_rig(obj):
        return curvenet.Rig.from_json(obj[RIG_KEY], obj.name + "[\"curvenet_rig\"]")
    rig = curvenet.Rig()
    rig.coverage = "auto"
    return rig


def set_rig(obj, rig):
    """Validates the rig by the engine's rules and sets it on the object."""
    curvenet.validate_rig(rig, obj.name)
    obj[RIG_KEY] = rig.to_json()


def rig_key(obj):
    """A digest of the object's rig text: what caches and results are kept with."""
    return hashlib.sha1(obj.get(RIG_KEY, "").encode()).hexdigest()[:20]


def clear_rig(obj):
    for key in (RIG_KEY, CONNECT_KEY, STARTER_KEY):
        if key in obj:
            del obj[key]
    state(obj).paths.clear()


def require_net(obj):
    """The object's rig, refused when it has no profile."""
    rig = get_rig(obj)
    if len(rig.profiles) == 0:
        raise Refused("%s has no net yet: draw profiles or make a starter net first." % obj.name)
    return rig


def _fresh_id(prefix, taken):
    i = 0
    while "%s%d" % (prefix, i) in taken:
        i += 1
    return "%s%d" % (prefix, i)


# --- drawing: nodes and profiles --------------------------------------------


def ray_to_object(obj, origin, direction):
    """A world-space ray in the object's space."""
    inv = obj.matrix_world.inverted()
    o = inv @ Vector(origin)
    d = (inv.to_3x3() @ Vector(direction)).normalized()
    return o, d


def surface_hit(obj, origin, direction):
    """Where a world-space ray first meets the rest surface, in object space, or None."""
    hit = surface_ray(obj, origin, direction)
    return None if hit is None else hit[0]


def surface_ray(obj, origin, direction):
    """(point, normal) where a world-space ray first meets the rest surface, object space, or None."""
    o, d = ray_to_object(obj, origin, direction)
    hit, normal, _face, _dist = surface_bvh(obj).ray_cast(o, d)
    if hit is None:
        return None
    return np.array(hit[:], dtype=np.float64), np.array(normal[:], dtype=np.float64)


def snap_radius(obj, point, normal, fraction=SNAP_FRACTION):
    """How near a click must come to a node to reuse it: `fraction` of the
    diagonal, but at most a third of the limb's thickness at the click (the
    distance through the mesh along the inward normal), so that the nodes of
    a ring round a thin leg stay apart."""
    st = state(obj)
    radius = fraction * st.diagonal
    inward = -np.asarray(normal, dtype=np.float64)
    start = np.asarray(point, dtype=np.float64) + 1e-5 * st.diagonal * inward
    far, _n, _f, through = surface_bvh(obj).ray_cast(Vector(start), Vector(inward))
    if far is not None and through is not None:
        radius = min(radius, through / 3.0)
    return radius


def nearest_node_within(rig, p, radius):
    best, best_d = None, radius
    for n in rig.nodes:
        d = float(np.linalg.norm(np.asarray(n.position) - p))
        if d <= best_d:
            best, best_d = n.id, d
    return best


def place(obj, origin, direction, snap=SNAP_FRACTION):
    """Where a click would put a node, without changing the rig: (point, the
    node it snaps to or None, the snap radius), or None when the ray misses."""
    hit = surface_ray(obj, origin, direction)
    if hit is None:
        return None
    p, normal = hit
    radius = snap_radius(obj, p, normal, snap)
    return p, nearest_node_within(get_rig(obj), p, radius), radius


def add_node_at(obj, origin, direction, snap=SNAP_FRACTION):
    """Casts a world-space ray into the surface and places a node where it hits.

    A hit within the snap radius of an existing node reuses that node.
    Returns the node's id, or None when the ray misses the mesh.
    """
    placed = place(obj, origin, direction, snap)
    if placed is None:
        return None
    p, node, _radius = placed
    if node is not None:
        return node
    rig = get_rig(obj)
    node = _fresh_id("n", {n.id for n in rig.nodes})
    rig.add_node(node, p)
    set_rig(obj, rig)
    return node


def surface_points_between(obj, a, b, count=8):
    """Points on the surface between two object-space points: the chord,
    split and pulled to the nearest surface point."""
    bvh = surface_bvh(obj)
    pts = [np.asarray(a, dtype=np.float64)]
    for i in range(1, count):
        q = Vector(tuple((1 - i / count) * np.asarray(a) + (i / count) * np.asarray(b)))
        near = bvh.find_nearest(q)[0]
        if near is not None:
            pts.append(np.array(near[:], dtype=np.float64))
    pts.append(np.asarray(b, dtype=np.float64))
    return np.array(pts)


def on_surface(obj, points):
    """The points pulled onto the rest surface (their nearest surface points)."""
    bvh = surface_bvh(obj)
    out = []
    for q in np.asarray(points, dtype=np.float64):
        near = bvh.find_nearest(Vector(q))[0]
        out.append(q if near is None else np.array(near[:]))
    return np.array(out).reshape(-1, 3)


def add_stroke(obj, a, b, via=None):
    """A profile from `a` to `b`, each a node id or an object-space point (a
    node is made there): the rig gains the profile and its new nodes at once,
    or nothing when the engine cannot trace it (curvenet.EmbedError).

    `via`: surface points the curve passes through between the ends (the
    stroke the user drew). Without it, the chord pulled onto the surface.
    Returns (profile id, first node, last node)."""
    rig = get_rig(obj)
    ids = []
    for end in (a, b):
        if isinstance(end, str):
            rig.node(end)  # KeyError when it does not exist
            ids.append(end)
        else:
            node = _fresh_id("n", {n.id for n in rig.nodes})
            rig.add_node(node, np.asarray(end, dtype=np.float64))
            ids.append(node)
    pa, pb = (np.asarray(rig.node(i).position) for i in ids)
    if via is None or len(via) == 0:
        pts = surface_points_between(obj, pa, pb)
    else:
        pts = np.vstack([pa[None], np.asarray(via, dtype=np.float64), pb[None]])
    profile_id = _fresh_id("p", {p.id for p in rig.profiles})
    rig.add_profile(profile_id, ids[0], ids[1], pts)
    _trace(obj, rig, [profile_id])  # raises before the rig changes
    set_rig(obj, rig)
    return profile_id, ids[0], ids[1]


def add_profile(obj, a, b, via=None):
    """Makes a profile from node `a` to node `b` and traces it on the surface
    (add_stroke with two nodes). Returns the profile id."""
    return add_stroke(obj, a, b, via)[0]


def remove_last_profile(obj):
    """Removes the last profile, and those of its end nodes no other profile
    uses (curvenet.remove_profiles: no orphan node stays). Returns the
    removed id, or None."""
    rig = get_rig(obj)
    if len(rig.profiles) == 0:
        return None
    pid = rig.profiles[len(rig.profiles) - 1].id
    set_rig(obj, curvenet.remove_profiles(rig, [pid], obj.name))
    return pid


def _signature(rig, p):
    a, b = rig.node(p.from_), rig.node(p.to)
    parts = (p.from_, p.to, p.curve.kind, np.asarray(a.position).tobytes(), np.asarray(b.position).tobytes(),
             np.asarray(p.curve.points).tobytes())
    return hashlib.sha1(repr(parts).encode()).hexdigest()


def _trace(obj, rig, ids, keep=True):
    """Traces the profiles `ids` of `rig` alone on the surface; keeps the
    paths with their curves' signatures (unless `keep` is False, for a
    preview) and returns them by id."""
    wanted = set(ids)
    alone = curvenet.Rig()
    alone.coverage = "local"
    ends = set()
    for p in rig.profiles:
        if p.id in wanted:
            ends |= {p.from_, p.to}
    for n in rig.nodes:
        if n.id in ends:
            alone.add_node(n.id, n.position)
    picked = [p for p in rig.profiles if p.id in wanted]
    for p in picked:
        q = alone.add_profile(p.id, p.from_, p.to)
        q.curve = p.curve
    paths = curvenet.trace_profiles(engine_mesh(obj), alone)
    st = state(obj)
    if keep:
        for p, path in zip(picked, paths):
            st.paths[p.id] = (_signature(rig, p), path)
    return {p.id: path for p, path in zip(picked, paths)}


def traced_paths(obj, rig=None):
    """Every profile's traced path (object space), tracing those whose curve
    or ends changed since they were traced (an edit, an undo, a load)."""
    st = state(obj)
    rig = rig or get_rig(obj)
    stale = [p.id for p in rig.profiles if st.paths.get(p.id, (None,))[0] != _signature(rig, p)]
    if stale:
        _trace(obj, rig, stale)
    return {p.id: st.paths[p.id][1] for p in rig.profiles}


# --- connect: embed and preview ---------------------------------------------


def connect(obj):
    """Embeds the object's rig in its mesh and shows the regions on a preview object.

    Returns (ok, report, message): the report is the CLI's, the message one
    line, "SUCCESS" or "FAILED" with the thesis's counts, or the engine's
    reason. The result is kept on the object with the rig it was made for
    (connect_result)."""
    rig = require_net(obj)
    try:
        emb = curvenet.embed(engine_mesh(obj), rig)
    except curvenet.Error as e:
        _keep_connect(obj, False, None, "FAILED: " + str(e), _named_profile(str(e), rig))
        return False, None, "FAILED: " + str(e)
    rep = emb.report
    st = state(obj)
    for pid, chain in emb.chains.items():
        st.paths[pid] = (_signature(rig, rig.profile(pid)), chain)
    make_preview(obj, emb)
    message = "%s: %d nodes, %d profiles, %d regions (expected %s), %d unmapped faces" % (
        "SUCCESS" if rep["ok"] else "FAILED",
        rep["logical_nodes"],
        rep["profiles"],
        rep["regions"],
        "-" if rep["expected_regions"] is None else rep["expected_regions"],
        rep["unmapped_faces"],
    )
    if not rep["ok"]:
        message += ": " + "; ".join(rep["problems"])
    _keep_connect(obj, rep["ok"], rep, message, "")
    return rep["ok"], rep, message


def _keep_connect(obj, ok, report, message, failed_profile):
    obj[CONNECT_KEY] = json.dumps(
        {"rig": rig_key(obj), "ok": ok, "report": report, "message": message, "failed_profile": failed_profile}
    )


def connect_result(obj):
    """The last Connect's result for the object's current rig: a dict with
    ok, report (None when the engine refused), message and failed_profile; or
    None when the rig has changed since (an edit, an undo) or was never connected."""
    text = obj.get(CONNECT_KEY) if obj is not None else None
    if not text:
        return None
    result = json.loads(text)
    return result if result.get("rig") == rig_key(obj) else None


def _named_profile(message, rig):
    """The profile an engine message names that was drawn last (rig order), to select it."""
    named = [p.id for p in rig.profiles if "'%s'" % p.id in message]
    return named[-1] if named else ""


def make_preview(obj, emb):
    """A separate object with the cut mesh and one colour per region (and the
    CutChains as a curve object), parented to the mesh. The mesh itself is
    never edited. The regions show in Solid shading as it is: each colour is
    a material's viewport colour (and a colour attribute, for Attribute
    shading and renders). The preview lies a hair outside the mesh
    (PREVIEW_LIFT), so the two never fight for depth; it cannot be selected,
    and it hides while the mesh is posed (sync_previews)."""
    V, offsets, corners = emb.cut_mesh()
    faces = [corners[offsets[f] : offsets[f + 1]].tolist() for f in range(len(offsets) - 1)]
    name = obj.name + PREVIEW_SUFFIX
    _remove_object(name)
    me = bpy.data.meshes.new(name)
    me.from_pydata(V.tolist(), [], faces)
    colours = emb.face_colours.astype(np.float32) / 255.0
    attr = me.color_attributes.new("regions", "BYTE_COLOR", "CORNER")
    loop_face = np.repeat(np.arange(len(faces)), np.diff(offsets))
    rgba = np.ones((len(loop_face), 4), dtype=np.float32)
    rgba[:, :3] = colours[loop_face]
    attr.data.foreach_set("color", rgba.ravel())
    regions = me.attributes.new("region", "INT", "FACE")
    regions.data.foreach_set("value", emb.face_regions.astype(np.int32))
    distinct, face_material = np.unique(emb.face_colours, axis=0, return_inverse=True)
    for rgb in distinct:
        me.materials.append(_region_material(rgb))
    me.polygons.foreach_set("material_index", face_material.astype(np.int32).ravel())
    me.update()
    # A hair outside the mesh it lies on, so that the two never fight for depth.
    normals = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("normal", normals)
    co = np.asarray(V, dtype=np.float64) + PREVIEW_LIFT * state(obj).diagonal * normals.reshape(-1, 3)
    me.vertices.foreach_set("co", co.ravel())
    me.update()
    preview = _attach(bpy.data.objects.new(name, me), obj)
    make_chains(obj, emb.chains)
    sync_previews(obj)
    return preview


def _region_material(rgb):
    """A material whose viewport colour is a region colour (0-255 RGB), shared by every preview."""
    name = "curvenet region %02x%02x%02x" % tuple(int(c) for c in rgb)
    mat = bpy.data.materials.get(name)
    if mat is None:
        mat = bpy.data.materials.new(name)
        colour = tuple(float(c) / 255.0 for c in rgb) + (1.0,)
        mat.diffuse_color = colour
        mat.use_nodes = True
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = colour
    return mat


def sync_previews(obj):
    """The region preview and the chains lie at rest: they show while the mesh
    is at rest and hide while it is posed (whichever deformation poses it)."""
    shown = not is_posed(obj)
    for suffix in (PREVIEW_SUFFIX, CHAINS_SUFFIX):
        o = bpy.data.objects.get(obj.name + suffix)
        if o is not None and o.hide_viewport == shown:  # only a change: each write is a depsgraph update
            o.hide_viewport = not shown
            o.hide_render = not shown


def make_chains(obj, chains):
    name = obj.name + CHAINS_SUFFIX
    _remove_object(name)
    cu = bpy.data.curves.new(name, "CURVE")
    cu.dimensions = "3D"
    cu.bevel_depth = 0.0015 * state(obj).diagonal
    cu.materials.append(_region_material((20, 20, 20)))
    for pts in chains.values():
        spline = cu.splines.new("POLY")
        spline.points.add(len(pts) - 1)
        co = np.ones((len(pts), 4))
        co[:, :3] = pts
        spline.points.foreach_set("co", co.ravel())
    return _attach(bpy.data.objects.new(name, cu), obj)


def _remove_object(name):
    """Removes a preview object of an earlier Connect, and its data."""
    old = bpy.data.objects.get(name)
    if old is not None:
        data = old.data
        bpy.data.objects.remove(old)
        if data is not None and data.users == 0:
            (bpy.data.meshes if isinstance(data, bpy.types.Mesh) else bpy.data.curves).remove(data)


def _attach(new, obj):
    """Links a preview object beside the mesh and parents it, in the mesh's space."""
    _link_like(new, obj)
    new.parent = obj
    new.matrix_parent_inverse = Matrix.Identity(4)
    new["curvenet_preview_of"] = obj.name
    new.hide_select = True  # a click on the character selects the character, not its preview
    return new


def _link_like(new, obj):
    cols = obj.users_collection or (bpy.context.scene.collection,)
    cols[0].objects.link(new)


# --- skeletons from armatures -----------------------------------------------


def armature_joints(obj, arm):
    """The armature's bones as joints in the mesh object's space, rest pose:
    bind = obj^-1 * arm * bone.matrix_local. Parents come first. The helper
    bones of a Bake to Vertex Groups are not joints: their constraint poses them."""
    to_obj = obj.matrix_world.inverted() @ arm.matrix_world
    joints = []
    for bone in _bones_parents_first(arm):
        if HELPER_KEY in bone:
            continue
        bind = np.array(to_obj @ bone.matrix_local, dtype=np.float64)
        joints.append(curvenet.Joint(bone.name, bone.parent.name if bone.parent else None, bind))
    return joints


def _bones_parents_first(arm):
    out, seen = [], set()

    def visit(b):
        if b.name in seen:
            return
        if b.parent is not None:
            visit(b.parent)
        seen.add(b.name)
        out.append(b)

    for b in arm.data.bones:
        visit(b)
    return out


def make_armature(obj, name=None):
    """An armature object from the rig's skeleton, placed with the mesh: one
    bone per joint, its head at the joint, its tail at its first child (a
    leaf continues its parent's direction at half its length)."""
    rig = get_rig(obj)
    if not rig.has_skeleton or len(rig.joints) == 0:
        raise Refused("The rig on %s has no skeleton to make an armature from: import a rig with one." % obj.name)
    existing = matching_armature(obj)
    if existing is not None:
        return existing  # the one made before, or the character's own: never a duplicate
    F = np.asarray(rig.frame)
    heads = {j.name: (F @ np.asarray(j.bind))[:3, 3] for j in rig.joints}
    children = {}
    for j in rig.joints:
        if j.parent is not None:
            children.setdefault(j.parent, []).append(j.name)
    data = bpy.data.armatures.new(name or obj.name + ".curvenet_armature")
    arm = bpy.data.objects.new(data.name, data)
    _link_like(arm, obj)
    arm.matrix_world = obj.matrix_world.copy()
    fallback = 0.05 * engine_mesh(obj).bbox_diagonal()
    view_layer = bpy.context.view_layer
    previous = view_layer.objects.active
    view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    bones = {}
    for j in rig.joints:
        b = data.edit_bones.new(j.name)
        head = heads[j.name]
        if j.name in children:
            tail = heads[children[j.name][0]]
        elif j.parent is not None:
            tail = head + 0.5 * (head - heads[j.parent])
        else:
            tail = head + np.array([0.0, 0.0, fallback])
        if np.linalg.norm(tail - head) < 1e-9 * fallback:
            tail = head + np.array([0.0, 0.0, fallback])
        b.head, b.tail = Vector(head), Vector(tail)
        if j.parent is not None:
            b.parent = bones[j.parent]
        bones[j.name] = b
    bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.objects.active = previous
    return arm


def deforming_bones(obj, arm):
    """The armature's bones that deform this mesh: Deform set, and a vertex
    group of the mesh's with that name (or every Deform bone when the mesh
    has no groups yet)."""
    groups = {g.name for g in obj.vertex_groups}
    bones = [b.name for b in arm.data.bones if b.use_deform and HELPER_KEY not in b]
    return [b for b in bones if b in groups] if groups else bones


def starter(obj, arm, **options):
    """A starter net from the armature's bones (rest pose), set as the object's
    rig; the joints left without a ring, and why, are kept with it (starter_notes).
    With vertex groups for the bones (a skinned mesh), each node takes their
    weights where it lies, as `curvenet starter` takes a file's skin."""
    options.setdefault("deforming", deforming_bones(obj, arm))
    joints = armature_joints(obj, arm)
    names = {j.name for j in joints}
    skeleton = skin_from_groups(obj, joints) if any(g.name in names for g in obj.vertex_groups) else joints
    result = curvenet.starter(engine_mesh(obj), skeleton, **options)
    set_rig(obj, result.rig)
    obj[STARTER_KEY] = json.dumps({"rig": rig_key(obj), "ringless": [list(x) for x in result.ringless]})
    return result


def starter_notes(obj):
    """[(joint, reason)] for the joints the last starter net left without a ring.
    Edits keep them (they are about the skeleton); a rig imported, transferred
    in or cleared takes them away."""
    text = obj.get(STARTER_KEY) if obj is not None else None
    if not text:
        return []
    return [tuple(x) for x in json.loads(text)["ringless"]]


def matching_armature(obj):
    """An armature in the file whose bones include every joint of the rig's skeleton, or None."""
    rig = get_rig(obj)
    names = {j.name for j in rig.joints}
    if not names:
        return None
    for o in bpy.data.objects:
        if o.type == "ARMATURE" and names <= {b.name for b in o.data.bones}:
            return o
    return None


# --- binding and live deformation -------------------------------------------


METHOD_KEY = "curvenet_method"
LAYER_KEY = "curvenet_layer"


def skin_from_groups(obj, joints):
    """The object's vertex groups as a skin over `joints` (matched to groups by
    bone name): each vertex's four largest weights, normalised, as the
    Armature modifier normalises them."""
    index = {j.name: i for i, j in enumerate(joints)}
    group_joint = {g.index: index.get(g.name, -1) for g in obj.vertex_groups}
    n = len(obj.data.vertices)
    J = np.full((n, 4), -1, dtype=np.int64)
    W = np.zeros((n, 4))
    for v in obj.data.vertices:
        ws = sorted(
            ((g.weight, group_joint.get(g.group, -1)) for g in v.groups if g.weight > 0),
            key=lambda x: -x[0],
        )
        ws = [x for x in ws if x[1] >= 0][:4]
        total = sum(w for w, _ in ws)
        for k, (w, j) in enumerate(ws):
            J[v.index, k] = j
            W[v.index, k] = w / total
    return curvenet.SkinnedMesh.from_weights(joints, J, W, obj.name)


def armature_modifier(obj, arm):
    for mod in obj.modifiers:
        if mod.type == "ARMATURE" and mod.object == arm:
            return mod
    return None


def _binding_source(obj, arm, method, layer):
    return (rig_key(obj), arm.name_full, method, bool(layer))


def _make_binding(obj, arm, method, layer):
    """Binds the object's rig to the armature (its bones replace the rig's
    skeleton, matched by name) into the runtime state; no modifier changes."""
    joints = armature_joints(obj, arm)
    rig = curvenet.with_skeleton(require_net(obj), joints, arm.name)
    if rig.to_json() != obj.get(RIG_KEY):
        set_rig(obj, rig)
    st = state(obj)
    mod = armature_modifier(obj, arm)
    if layer and mod is None:
        raise Refused("A layer sits on an Armature modifier: give %s one on %s first." % (obj.name, arm.name))
    if layer:
        skinning = "dq" if mod.use_deform_preserve_volume else "linear"
        st.layer = curvenet.bind_layer(
            engine_mesh(obj), rig, skin=skin_from_groups(obj, joints), skinning=skinning, method=method
        )
        st.binding = st.layer.binding
        st.rest = rest_arrays(obj)[0].astype(np.float32)
    else:
        st.layer = None
        st.binding = curvenet.bind(engine_mesh(obj), rig, method=method)
    st.binding_for = _binding_source(obj, arm, method, layer)
    st.net_layer = None
    names = {b.name for b in arm.data.bones}
    st.bone_names = [n if n in names else None for n in st.binding.joint_names]
    st.node_rest = {n.id: np.array(n.position) for n in rig.nodes}
    st.matrices = np.empty((len(st.bone_names), 4, 4), dtype=np.float64)
    st.positions = np.empty((st.binding.num_input_vertices, 3), dtype=np.float32)
    st.last_pose = None
    return st.binding


def bind(obj, arm, method=None, layer=None):
    """Binds the object's rig to the armature and makes the net the one
    deformation that plays: 'live' (the net alone) or 'layer' (over the
    Armature modifier, through a corrective shape key in rest space;
    docs/blender.md). method: 'dq', 'harmonic' or 'gradient'
    (docs/deform.md). Both default to the object's last."""
    method = method or obj.get(METHOD_KEY, "dq")
    layer = bool(obj.get(LAYER_KEY, False)) if layer is None else bool(layer)
    binding = _make_binding(obj, arm, method, layer)
    obj[METHOD_KEY] = method
    obj[LAYER_KEY] = layer
    obj[ARMATURE_KEY] = arm
    set_deformation(obj, "layer" if layer else "live", arm)
    update_live(obj, force=True)
    return binding


# --- one deformation at a time ----------------------------------------------

# What can deform a mesh, and what each is made of:
# - rest: nothing;
# - skin: the mesh's own Armature modifier (Curvenet is not involved);
# - live: the net, through the shape key `curvenet`; every Armature modifier off;
# - layer: the net over the Armature modifier on the bound armature: the shape
#   key holds the correction, the modifier moves it; other Armature modifiers off;
# - cache: the Mesh Cache modifier `curvenet` playing a baked PC2; Armature modifiers off;
# - groups: the baked vertex groups, through an Armature modifier on the armature.
DEFORMATIONS = ("rest", "skin", "live", "layer", "cache", "groups")
CACHE_MODIFIER = "curvenet"
DESCRIPTIONS = {
    "rest": "nothing deforms the mesh",
    "skin": "the mesh's own Armature modifier",
    "live": "Curvenet, live",
    "layer": "Curvenet layered over the Armature modifier",
    "cache": "the baked point cache (Mesh Cache modifier)",
    "groups": "the baked vertex groups (Armature modifier)",
}


def deformation(obj):
    """Which deformation plays on the mesh (one of DEFORMATIONS)."""
    kind = obj.get(DEFORMATION_KEY)
    if kind in DEFORMATIONS:
        return kind
    return "skin" if any(m.type == "ARMATURE" and m.show_viewport for m in obj.modifiers) else "rest"


def active_deformers(obj):
    """What actually moves the mesh now: the enabled Armature and Mesh Cache
    modifiers, and the shape key `curvenet` when it acts. The tests check it
    against deformation()."""
    out = [("modifier", m.type, m.name) for m in obj.modifiers
           if m.type in ("ARMATURE", "MESH_CACHE") and m.show_viewport]
    keys = obj.data.shape_keys
    key = keys.key_blocks.get(SHAPE_KEY) if keys is not None else None
    if key is not None and key.value > 0 and not key.mute:
        out.append(("shape key", SHAPE_KEY, SHAPE_KEY))
    return out


def describe_deformation(obj):
    kind = deformation(obj)
    arm = bound_armature(obj)
    text = DESCRIPTIONS[kind]
    if kind in ("live", "layer", "groups") and arm is not None:
        text += " on " + arm.name
    return text


def set_deformation(obj, kind, arm=None):
    """Makes `kind` the one deformation that plays: removes the shape key and
    the cache modifier it does not use, and switches Armature modifiers off
    (remembering the mesh's own) or back on. Returns the kind."""
    if kind not in DEFORMATIONS:
        raise ValueError("deformation: expected one of " + ", ".join(DEFORMATIONS))
    if kind in ("live", "layer"):
        key = _ensure_shape_key(obj)
        if kind == "live":  # the net alone: the whole of it, everywhere
            key.value = 1.0
            key.vertex_group = ""
    else:
        _remove_shape_key(obj)
    if kind != "cache":
        mod = obj.modifiers.get(CACHE_MODIFIER)
        if mod is not None and mod.type == "MESH_CACHE":
            obj.modifiers.remove(mod)
    own = set(filter(None, obj.get(MODIFIERS_KEY, "").split("\n")))  # the mesh's own, switched off by us
    for mod in obj.modifiers:
        if mod.type != "ARMATURE":
            continue
        keep = kind in ("layer", "groups") and arm is not None and mod.object == arm
        if kind in ("rest", "skin"):
            if mod.name in own:
                mod.show_viewport = mod.show_render = True
            continue
        if keep:
            mod.show_viewport = mod.show_render = True
        elif mod.show_viewport or mod.show_render:
            own.add(mod.name)
            mod.show_viewport = mod.show_render = False
    if kind in ("rest", "skin"):
        own = set()
        if kind == "skin" and not any(m.type == "ARMATURE" and m.show_viewport for m in obj.modifiers):
            kind = "rest"
        elif kind == "rest" and any(m.type == "ARMATURE" and m.show_viewport for m in obj.modifiers):
            kind = "skin"
    if own:
        obj[MODIFIERS_KEY] = "\n".join(sorted(own))
    elif MODIFIERS_KEY in obj:
        del obj[MODIFIERS_KEY]
    obj[DEFORMATION_KEY] = kind
    sync_previews(obj)
    obj.data.update()
    return kind


def _ensure_shape_key(obj):
    """The shape key `curvenet`, made at value 1 when missing; an existing
    one keeps its value and vertex group (a layer's envelope and mask)."""
    me = obj.data
    if me.shape_keys is None:
        obj.shape_key_add(name="Basis", from_mix=False)
    key = me.shape_keys.key_blocks.get(SHAPE_KEY)
    if key is None:
        key = obj.shape_key_add(name=SHAPE_KEY, from_mix=False)
        key.value = 1.0
    key.slider_min = 0.0
    key.slider_max = 1.0
    key.mute = False
    return key


def layer_key(obj):
    """The shape key that holds a layered mesh's correction, or None when the
    mesh is not layered. Its value is the layer's envelope (keyable on the
    timeline) and its vertex group the mask: Blender scales the correction
    by both, and the Armature modifier then moves it (docs/blender.md)."""
    if deformation(obj) != "layer" or obj.data.shape_keys is None:
        return None
    return obj.data.shape_keys.key_blocks.get(SHAPE_KEY)


def group_weights(obj, name):
    """Per vertex, its weight in the vertex group `name` (0 outside it)."""
    group = obj.vertex_groups.get(name)
    w = np.zeros(len(obj.data.vertices))
    if group is None:
        return w
    gi = group.index
    for v in obj.data.vertices:
        for g in v.groups:
            if g.group == gi:
                w[v.index] = g.weight
    return w


def _remove_shape_key(obj):
    me = obj.data
    if me.shape_keys is not None:
        key = me.shape_keys.key_blocks.get(SHAPE_KEY)
        if key is not None:
            obj.shape_key_remove(key)


def unbind(obj):
    """Stops every Curvenet deformation (live, layer, cache): the mesh's own
    Armature modifiers come back, or it rests. Returns the deformation left."""
    st = state(obj)
    st.binding = st.layer = st.net_layer = None
    st.binding_for = None
    return set_deformation(obj, "skin")


def bound_armature(obj):
    """The armature the mesh was bound to (a pointer: renaming keeps it; a
    name in files from before)."""
    value = obj.get(ARMATURE_KEY)
    arm = bpy.data.objects.get(value) if isinstance(value, str) else value
    return arm if isinstance(arm, bpy.types.Object) and arm.type == "ARMATURE" else None


def ensure_binding(obj):
    """The object's binding, made again when it is missing or was made from
    another rig, armature or method (an undo, a redo, a file load)."""
    arm = bound_armature(obj)
    if arm is None or not has_rig(obj):
        return None
    st = state(obj)
    method = obj.get(METHOD_KEY, "dq")
    layer = bool(obj.get(LAYER_KEY, False))
    if st.binding is None or st.binding_for != _binding_source(obj, arm, method, layer):
        _make_binding(obj, arm, method, layer)
    return st.binding


def skinning_matrices(obj, arm, out=None, depsgraph=None):
    """The binding's skinning matrices (J, 4, 4) from the armature's current
    pose, in the mesh's object space: M = O^-1 A P L^-1 A^-1 O, with O and A
    the objects' world matrices, P the pose bone's and L the bone's rest matrix."""
    st = state(obj)
    if out is None:
        out = np.empty((len(st.bone_names), 4, 4))
    source = arm.evaluated_get(depsgraph) if depsgraph is not None else arm
    to_obj = obj.matrix_world.inverted() @ source.matrix_world
    from_obj = source.matrix_world.inverted() @ obj.matrix_world
    bones = source.pose.bones
    for j, name in enumerate(st.bone_names):
        if name is None:
            out[j] = np.eye(4)
            continue
        pb = bones[name]
        out[j] = to_obj @ pb.matrix @ pb.bone.matrix_local.inverted() @ from_obj
    return out


# --- pulling nodes: empties that give nodes offsets ------------------------

HANDLE_KEY = "curvenet_node"  # on an empty: the node it pulls
HANDLE_MESH_KEY = "curvenet_node_of"  # on an empty: the mesh object whose node it is


def node_handles(obj):
    return [o for o in bpy.data.objects if o.type == "EMPTY" and o.get(HANDLE_MESH_KEY) == obj.name and HANDLE_KEY in o]


def _heaviest_bone(obj, node):
    all_weights = ensure_binding(obj).node_weights
    weights = dict(all_weights[node]) if node in all_weights else {}
    if not weights:
        raise Refused("Node %s of %s has no weights: bind it first." % (node, obj.name))
    return max(weights.items(), key=lambda kv: kv[1])[0]


def add_node_handle(obj, node):
    """An empty that pulls `node`: it rides on the node's heaviest bone, and
    moving it (or keying it on the timeline) gives the node an offset, which
    the curves through the node and the regions they bound follow. A node
    that has a handle keeps it: that handle is returned."""
    for e in node_handles(obj):
        if e[HANDLE_KEY] == node:
            return e
    arm = bound_armature(obj)
    if arm is None or ensure_binding(obj) is None:
        raise Refused("Bind %s to an armature first." % obj.name)
    rig = get_rig(obj)
    if rig.node_index(node) < 0:
        raise Refused("%s's net has no node %s." % (obj.name, node))
    rest = rig.node(node).position
    bone = _heaviest_bone(obj, node)
    st = state(obj)
    M = skinning_matrices(obj, arm)
    posed = (M[st.bone_names.index(bone)] @ np.append(rest, 1.0))[:3]
    e = bpy.data.objects.new("%s.node.%s" % (obj.name, node), None)
    e.empty_display_type = "SPHERE"
    e.empty_display_size = 0.01 * st.diagonal
    _link_like(e, obj)
    e[HANDLE_KEY] = node
    e[HANDLE_MESH_KEY] = obj.name
    e.parent = arm
    e.parent_type = "BONE"
    e.parent_bone = bone
    bpy.context.view_layer.update()
    e.matrix_world = obj.matrix_world @ Matrix.Translation(Vector(posed))
    return e


def node_offsets(obj, depsgraph=None):
    """Each handle's node offset in rest space: the handle's place brought
    back to rest through its bone's skinning matrix, minus the node's rest
    position (state(obj).matrices must be the current pose's)."""
    handles = node_handles(obj)
    if not handles:
        return {}
    st = state(obj)
    to_obj = obj.matrix_world.inverted()
    out = {}
    for e in handles:
        node = e[HANDLE_KEY]
        if node not in st.node_rest:  # the bound rig's nodes, not parsed again each frame
            continue
        source = e.evaluated_get(depsgraph) if depsgraph is not None else e
        p = to_obj @ source.matrix_world.translation
        j = st.bone_names.index(e.parent_bone) if e.parent_bone in st.bone_names else -1
        if j < 0:
            continue
        rest = np.linalg.solve(st.matrices[j], np.append(np.array(p), 1.0))[:3]
        offset = rest - st.node_rest[node]
        if np.linalg.norm(offset) > 1e-9 * st.diagonal:
            out[node] = offset
    return out


def update_live(obj, depsgraph=None, force=False):
    """Deforms the mesh for the armature's current pose into the shape key.
    Returns True when positions were written. Allocates no arrays."""
    st = state(obj)
    arm = bound_armature(obj)
    if st.binding is None or arm is None:
        return False
    skinning_matrices(obj, arm, st.matrices, depsgraph)
    if st.last_pose is None:
        st.last_pose = np.full_like(st.matrices, np.nan)
        st.changed = np.empty(st.matrices.shape, dtype=bool)
    pulled = bool(node_handles(obj))  # a moved handle changes no bone: update whenever there are handles
    if not force and not pulled and not np.not_equal(st.last_pose, st.matrices, out=st.changed).any():
        return False
    st.last_pose[...] = st.matrices
    offsets = node_offsets(obj, depsgraph)
    if st.layer is not None:  # the rest position and the correction, for the Armature modifier to move
        np.add(st.rest, st.layer.rest_correction(st.matrices, offsets=offsets), out=st.positions, casting="unsafe")
    elif offsets:  # pulled nodes: through a layer over the net itself
        if st.net_layer is None:
            st.net_layer = curvenet.bind_layer(engine_mesh(obj), get_rig(obj), method=obj.get(METHOD_KEY, "dq"))
        st.positions[...] = st.net_layer.deform(st.matrices, offsets=offsets)
    else:
        st.binding.deform(st.matrices, out=st.positions)
    key = obj.data.shape_keys.key_blocks.get(SHAPE_KEY) if obj.data.shape_keys else None
    if key is None:
        return False
    key.data.foreach_set("co", st.positions.ravel())
    obj.data.update()
    return True


def is_posed(obj):
    """Whether the mesh is shown away from its rest shape (a deformation playing, the pose not the rest pose)."""
    kind = deformation(obj)
    if kind in ("rest", "skin") and not any(m.type == "ARMATURE" and m.show_viewport for m in obj.modifiers):
        return False
    arm = bound_armature(obj) or next((m.object for m in obj.modifiers if m.type == "ARMATURE" and m.object), None)
    if arm is None:
        return kind == "cache"
    scale = max(1.0, max((b.length for b in arm.data.bones), default=1.0))
    for pb in arm.pose.bones:  # a bone away from its rest place moves what it skins
        if not np.allclose(np.array(pb.matrix), np.array(pb.bone.matrix_local), atol=1e-6 * scale):
            return True
    return kind == "cache"


def previewed_objects():
    """The meshes that have a region preview."""
    out = []
    for o in bpy.data.objects:
        owner = o.get("curvenet_preview_of")
        if owner and o.name.endswith(PREVIEW_SUFFIX):
            mesh = bpy.data.objects.get(owner)
            if mesh is not None:
                out.append(mesh)
    return out


def live_objects():
    """The meshes the net deforms now (live or layered)."""
    return [o for o in bpy.data.objects
            if o.type == "MESH" and o.get(DEFORMATION_KEY) in ("live", "layer") and has_rig(o)]


HELPER_KEY = "curvenet_helper"  # on a helper bone: its two joints, "a|b"
HELPER_LAYER = 31  # the bone layer helper bones are put on (hidden unless shown)


def _remove_helper_bones(arm):
    """Removes the helper bones an earlier Bake to Vertex Groups made."""
    names = [b.name for b in arm.data.bones if HELPER_KEY in b]
    if not names:
        return
    view_layer = bpy.context.view_layer
    previous = view_layer.objects.active
    view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    for name in names:
        eb = arm.data.edit_bones.get(name)
        if eb is not None:
            arm.data.edit_bones.remove(eb)
    bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.objects.active = previous


def _add_helper_bones(arm, w):
    """A bone for each helper joint of the weights: at the rest place of the
    deeper of its two bones, with no parent, and posed by an Armature
    constraint on the two at half weight each with Preserve Volume, which
    blends them as dual quaternions: helper_matrix, in stock Blender.
    Returns the weights' helper names -> the bones' names."""
    rig_count = len(w.joints) - len(w.helpers)

    def depth(name):
        d, b = 0, arm.data.bones[name]
        while b.parent is not None:
            d, b = d + 1, b.parent
        return d

    view_layer = bpy.context.view_layer
    previous = view_layer.objects.active
    view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    made = {}
    for h, (a, b) in enumerate(w.helpers):
        na, nb = w.joints[a], w.joints[b]
        under = arm.data.edit_bones[nb if depth(nb) > depth(na) else na]
        eb = arm.data.edit_bones.new(w.joints[rig_count + h])
        eb.head, eb.tail, eb.roll = under.head.copy(), under.tail.copy(), under.roll
        eb.use_deform = True
        made[w.joints[rig_count + h]] = (eb.name, na, nb)
    bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.objects.active = previous
    names = {}
    for helper, (bone, na, nb) in made.items():
        arm.data.bones[bone][HELPER_KEY] = na + "|" + nb
        if hasattr(arm.data.bones[bone], "layers"):  # out of the way: on the last bone layer alone
            arm.data.bones[bone].layers = [i == HELPER_LAYER for i in range(32)]
        pb = arm.pose.bones[bone]
        c = pb.constraints.new("ARMATURE")
        c.name = "curvenet helper"
        c.use_deform_preserve_volume = True
        for target in (na, nb):
            t = c.targets.new()
            t.target, t.subtarget, t.weight = arm, target, 0.5
        names[helper] = bone
    return names


def bake_vertex_groups(obj, arm, max_influences=4, fitted=False, helpers=0):
    """Bakes the binding to an ordinary skin: the top-k weights of each
    vertex (or, `fitted`, weights fitted to the net's own deformation over
    poses of the skeleton, as `curvenet bake --weights fitted` fits them) as
    vertex groups named after the bones, and an Armature modifier on the
    armature, which becomes the one deformation ('groups'): the mesh then
    plays with stock Blender, without the add-on. With `helpers` (fitted
    only), up to that many helper bones, each half way between two bones
    (`curvenet bake --helpers`): made by _add_helper_bones, and removed by
    the next bake. Returns the curvenet.SkinWeights."""
    if helpers and not fitted:
        raise Refused("Helper bones are fitted with the weights: choose Fitted weights.")
    if bound_armature(obj) != arm:
        obj[ARMATURE_KEY] = arm
    binding = ensure_binding(obj)
    if binding is None:
        raise Refused("Bind %s to an armature first." % obj.name)
    if fitted:
        w = curvenet.fit_weights(binding, curvenet.training_poses(binding), max_influences, helpers=helpers)
    else:
        w = curvenet.bake_weights(binding, max_influences)
    # Groups named after bones deform with them: those of another skin go,
    # and so do the helper bones of an earlier bake.
    bones = {b.name for b in arm.data.bones}
    for vg in list(obj.vertex_groups):
        if vg.name in bones:
            obj.vertex_groups.remove(vg)
    _remove_helper_bones(arm)
    bone_of = _add_helper_bones(arm, w) if w.helpers else {}
    groups = {}
    J, Wt = w.joint, w.weight
    for v in range(w.num_vertices):
        for i in range(w.influences):
            j = int(J[v, i])
            if j < 0:
                continue
            name = bone_of.get(w.joints[j], w.joints[j])
            vg = groups.get(name)
            if vg is None:
                vg = groups[name] = obj.vertex_groups.new(name=name)
            vg.add([v], float(Wt[v, i]), "REPLACE")
    mod = armature_modifier(obj, arm) or next((m for m in obj.modifiers if m.type == "ARMATURE"), None)
    if mod is None:
        mod = obj.modifiers.new("Armature", "ARMATURE")
    mod.object = arm
    mod.use_vertex_groups = True
    mod.use_bone_envelopes = False
    mod.use_deform_preserve_volume = False
    st = state(obj)
    st.binding = st.layer = st.net_layer = None
    st.binding_for = None
    set_deformation(obj, "groups", arm)
    return w


# --- node weights -----------------------------------------------------------


def set_node_weight(obj, nodes, bone, weight):
    """Sets the weight of `bone` on each node, scaling the node's other joints
    so that the weights still sum to 1 (the thesis's sparse editor;
    curvenet.set_joint_weight). Nodes without weights start from their
    automatic ones. The live deformation follows."""
    if not 0.0 <= weight <= 1.0 or math.isnan(weight):
        raise Refused("A weight is a number from 0 to 1, not %s." % weight)
    rig = get_rig(obj)
    if not rig.has_skeleton:
        raise Refused("The net on %s has no skeleton yet: bind it or make a starter net first." % obj.name)
    rig = curvenet.set_joint_weight(rig, list(nodes), bone, weight, obj.name)
    set_rig(obj, rig)
    if deformation(obj) in ("live", "layer"):
        ensure_binding(obj)
        update_live(obj, force=True)
    return rig


def node_weights(obj, node):
    """The node's weights as the binding uses them (given or automatic)."""
    st = state(obj)
    if st.binding is not None and st.binding_for and st.binding_for[0] == rig_key(obj):
        weights = st.binding.node_weights  # a bound map: no get()
        return dict(weights[node]) if node in weights else {}
    rig = get_rig(obj)
    if not rig.has_skeleton:
        return {}
    return dict(curvenet.complete_weights(rig).weights[node])


def nearest_node(obj, origin, direction):
    """The node nearest to where a world-space ray meets the surface (or to the ray)."""
    rig = get_rig(obj)
    if len(rig.nodes) == 0:
        return None
    p = surface_hit(obj, origin, direction)
    o, d = ray_to_object(obj, origin, direction)
    best, best_d = None, float("inf")
    for n in rig.nodes:
        q = np.asarray(n.position)
        if p is not None:
            dist = float(np.linalg.norm(q - p))
        else:
            v = q - np.array(o[:])
            dist = float(np.linalg.norm(v - np.dot(v, d[:]) * np.array(d[:])))
        if dist < best_d:
            best, best_d = n.id, dist
    return best


# --- transfer, files, cache -------------------------------------------------


def transfer(obj, target):
    """Transfers the object's rig to another mesh object of the same character
    (world matrices as the common frame). Sets the target's rig when it
    succeeds; returns the curvenet.TransferResult."""
    rig = get_rig(obj)
    result = curvenet.transfer(
        rig,
        engine_mesh(obj),
        engine_mesh(target),
        source_frame=np.array(obj.matrix_world),
        target_frame=np.array(target.matrix_world),
    )
    if result.ok:
        set_rig(target, result.rig)
        if STARTER_KEY in target:
            del target[STARTER_KEY]
        state(target).paths.clear()
    return result


# Blender's glTF importer turns a Y-up file to Z-up in the mesh data: file
# (x, y, z) -> Blender (x, -z, y). OBJ's importer keeps the data and turns the object.
Y_UP_TO_BLENDER = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])


def apply_frame(rig, F):
    """The rig with the similarity F applied to its coordinates (nodes, curve
    points, joints), and its frame the identity: the rig in F's target space."""
    F = np.asarray(F, dtype=np.float64)
    out = rig.copy()
    out.frame = np.eye(4)

    def move(p):
        return F[:3, :3] @ np.asarray(p) + F[:3, 3]

    for n in out.nodes:
        n.position = move(n.position)
    for p in out.profiles:
        pts = p.curve.points
        if len(pts):
            c = p.curve
            c.points = pts @ F[:3, :3].T + F[:3, 3]
            p.curve = c
    for j in out.joints:
        j.bind = F @ np.asarray(j.bind)
    return out


def _off_surface(obj, rig):
    """How far the rig's nodes lie from the rest surface, on average (object space)."""
    bvh = surface_bvh(obj)
    F = np.asarray(rig.frame)
    d = [bvh.find_nearest(Vector(tuple(F[:3, :3] @ np.asarray(n.position) + F[:3, 3])))[3] for n in rig.nodes]
    d = [x for x in d if x is not None]
    return float(np.mean(d)) if d else 0.0


def export_rig(obj, path, up="Z"):
    """Writes the rig. up 'Z': in the object's own (Blender) space; 'Y': in the
    space of the Y-up file it was imported from (glTF), for the CLI."""
    rig = get_rig(obj)
    if up == "Y":
        rig = apply_frame(rig, np.linalg.inv(Y_UP_TO_BLENDER) @ np.asarray(rig.frame))
    curvenet.write_rig(rig, path)


def import_rig(obj, path, up="AUTO"):
    """Reads a rig onto the object, in its object space. up 'Z': the rig is in
    Blender's space; 'Y': in a Y-up file's (a rig made with the CLI on the
    glTF Blender imported); 'AUTO': whichever puts the nodes nearer the surface."""
    rig = curvenet.read_rig(path)
    frame = np.asarray(rig.frame)
    if up == "AUTO" and len(rig.nodes):
        turned = rig.copy()
        turned.frame = Y_UP_TO_BLENDER @ frame
        up = "Y" if _off_surface(obj, turned) < _off_surface(obj, rig) else "Z"
    F = Y_UP_TO_BLENDER @ frame if up == "Y" else frame
    rig = apply_frame(rig, F)
    set_rig(obj, rig)
    if STARTER_KEY in obj:
        del obj[STARTER_KEY]
    state(obj).paths.clear()
    return rig


def clip_range(obj, scene=None):
    """The frames to bake: the bound armature's action (its clip), else the scene's range."""
    scene = scene or bpy.context.scene
    arm = bound_armature(obj)
    action = arm.animation_data.action if arm is not None and arm.animation_data else None
    if action is not None:
        start, end = action.frame_range
        return int(math.floor(start)), int(math.ceil(end))
    return scene.frame_start, scene.frame_end


def bake_cache(obj, path, frame_start=None, frame_end=None, scene=None):
    """Writes the deformation of frames [start, end] (by default the clip's,
    clip_range) as a PC2 cache and makes its Mesh Cache modifier the one
    deformation ('cache'), so the .blend plays without the add-on."""
    scene = scene or bpy.context.scene
    if not path or os.path.basename(path) in ("", ".pc2"):
        raise Refused("Choose a file for the cache: the path is empty.")
    default_start, default_end = clip_range(obj, scene)
    frame_start = default_start if frame_start is None else frame_start
    frame_end = default_end if frame_end is None else frame_end
    if frame_end < frame_start:
        raise Refused("The last frame (%d) comes before the first (%d)." % (frame_end, frame_start))
    binding = ensure_binding(obj)
    arm = bound_armature(obj)
    if binding is None or arm is None:
        raise Refused("Bind %s to an armature first." % obj.name)
    st = state(obj)
    M = st.matrices  # the pose's matrices, which node_offsets reads too
    current = scene.frame_current
    # What plays is what is baked: a layer with its keyed envelope, its mask
    # and its pulled nodes; the net with its pulled nodes; or the net.
    key = layer_key(obj)
    handles = bool(node_handles(obj))
    if st.layer is not None and key is not None:
        deformer = st.layer.with_mask(group_weights(obj, key.vertex_group) if key.vertex_group else None)
    elif handles:
        if st.net_layer is None:
            st.net_layer = curvenet.bind_layer(engine_mesh(obj), get_rig(obj), method=obj.get(METHOD_KEY, "dq"))
        deformer = st.net_layer
    else:
        deformer = binding

    def pose(f):
        scene.frame_set(f)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        skinning_matrices(obj, arm, M, depsgraph)
        if deformer is binding:
            return M
        envelope = 0.0 if key is not None and key.mute else 1.0 if key is None else min(max(key.value, 0.0), 1.0)
        return M, envelope, node_offsets(obj, depsgraph)

    try:
        # The library's frame job: blocks of bounded memory, streamed to the cache.
        curvenet.animate_poses(deformer, pose, frame_start, frame_end, path, fps=scene.render.fps)
    finally:
        scene.frame_set(current)
    set_deformation(obj, "cache", arm)
    old = obj.modifiers.get(CACHE_MODIFIER)
    if old is not None and old.type == "MESH_CACHE":  # a bake over a bake replaces its cache
        obj.modifiers.remove(old)
    mod = obj.modifiers.new(CACHE_MODIFIER, "MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = path
    # The cache holds object-space positions in Blender's own axes and vertex order.
    mod.forward_axis = "POS_Y"
    mod.up_axis = "POS_Z"
    mod.frame_start = frame_start
    mod.frame_scale = 1.0
    with bpy.context.temp_override(object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=mod.name, index=0)
    return frame_start, frame_end
