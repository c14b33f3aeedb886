"""The add-on's non-modal core: every step of the workflow as a function of
Blender objects, with no operator, no event and no UI. The operators
(operators.py) are thin shells over these, and the tests call them directly.

Where things live:
- The rig is the object's custom property ``curvenet_rig`` (rig-file JSON,
  the mesh's object space), so it is saved in the .blend and exports as a
  ``.cnrig.json`` unchanged.
- The armature a mesh is bound to is the object's ``curvenet_armature``.
- Bindings, engine meshes and traced paths are runtime caches (``STATE``),
  rebuilt on demand and after a file is loaded.
- Deformed positions go to a shape key ``curvenet`` on top of the basis:
  the user's rest mesh is never edited.
"""

import math

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
CHAINS_SUFFIX = ".curvenet_chains"
# A click this close to an existing node (a fraction of the mesh's bounding-box
# diagonal) reuses that node.
SNAP_FRACTION = 0.02


class ObjectState:
    """What the add-on keeps for one mesh object while Blender runs."""

    def __init__(self):
        self.mesh_key = None  # what the engine mesh and BVH were built from
        self.mesh = None  # curvenet.Mesh of the rest positions, Blender's vertex order
        self.bvh = None
        self.diagonal = 1.0
        self.paths = {}  # profile id -> (k, 3) traced path, object space
        self.last_nodes = []  # the node each profile of the current stroke started from
        self.binding = None
        self.layer = None  # curvenet.CurveLayer when the net is layered over the Armature modifier
        self.rest = None  # (n, 3) rest positions, for the layer's corrective shape key
        self.net_layer = None  # curvenet.CurveLayer over the net itself, for pulled nodes without a skin
        self.bone_names = []  # per binding joint, the armature bone that drives it
        self.matrices = None  # (J, 4, 4) scratch, filled per frame
        self.positions = None  # (n, 3) float32 scratch
        self.last_pose = None  # the matrices of the last update, to skip unchanged poses
        self.changed = None  # scratch for comparing them
        self.report = None  # the last Connect's report
        self.error = ""  # the last failure, one line
        self.failed_profile = ""


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
    curvenet.validate_rig(rig, obj.name)
    obj[RIG_KEY] = rig.to_json()


def clear_rig(obj):
    if RIG_KEY in obj:
        del obj[RIG_KEY]
    state(obj).paths.clear()
    state(obj).last_nodes.clear()


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
    o, d = ray_to_object(obj, origin, direction)
    hit, _normal, _face, _dist = surface_bvh(obj).ray_cast(o, d)
    return None if hit is None else np.array(hit[:], dtype=np.float64)


def add_node_at(obj, origin, direction, snap=SNAP_FRACTION):
    """Casts a world-space ray into the surface and places a node where it hits.

    A hit within `snap` of the diagonal of an existing node reuses that node.
    Returns the node's id, or None when the ray misses the mesh.
    """
    p = surface_hit(obj, origin, direction)
    if p is None:
        return None
    rig = get_rig(obj)
    tolerance = snap * state(obj).diagonal
    best, best_d = None, tolerance
    for n in rig.nodes:
        d = float(np.linalg.norm(np.asarray(n.position) - p))
        if d <= best_d:
            best, best_d = n.id, d
    if best is not None:
        return best
    node_id = _fresh_id("n", {n.id for n in rig.nodes})
    rig.add_node(node_id, p)
    set_rig(obj, rig)
    return node_id


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


def add_profile(obj, a, b, via=None):
    """Makes a profile from node `a` to node `b` and traces it on the surface.

    `via`: surface points the curve passes through between the nodes (the
    stroke the user drew), object space. Without it, the chord pulled onto
    the surface. Returns the profile id. Raises curvenet.EmbedError (and adds
    nothing) when the engine cannot trace it.
    """
    rig = get_rig(obj)
    na, nb = rig.node(a), rig.node(b)
    if via is None or len(via) == 0:
        pts = surface_points_between(obj, na.position, nb.position)
    else:
        pts = np.vstack([np.asarray(na.position)[None], np.asarray(via, dtype=np.float64), np.asarray(nb.position)[None]])
    profile_id = _fresh_id("p", {p.id for p in rig.profiles})
    rig.add_profile(profile_id, a, b, pts)
    # Trace it alone: the path the cut will follow on this surface.
    alone = curvenet.Rig()
    alone.coverage = "local"
    alone.add_node(a, na.position)
    if b != a:
        alone.add_node(b, nb.position)
    alone.add_profile(profile_id, a, b, pts)
    path = curvenet.trace_profiles(engine_mesh(obj), alone)[0]
    set_rig(obj, rig)
    st = state(obj)
    st.paths[profile_id] = path
    st.last_nodes.append(a)
    return profile_id


def remove_last_profile(obj):
    """Removes the last profile, and its end node when no other profile uses
    it (the stroke goes back to the profile's first node). Returns the
    removed id, or None."""
    rig = get_rig(obj)
    if len(rig.profiles) == 0:
        return None
    last = rig.profiles[len(rig.profiles) - 1]
    pid, start, end = last.id, last.from_, last.to
    del rig.profiles[len(rig.profiles) - 1]
    used = {p.from_ for p in rig.profiles} | {p.to for p in rig.profiles}
    if end != start and end not in used:
        idx = rig.node_index(end)
        del rig.nodes[idx]
        if end in rig.weights:
            del rig.weights[end]
    set_rig(obj, rig)
    st = state(obj)
    st.paths.pop(pid, None)
    if st.last_nodes:
        st.last_nodes.pop()
    return pid


def traced_paths(obj):
    """Every profile's traced path (object space), tracing those not yet traced."""
    st = state(obj)
    rig = get_rig(obj)
    ids = [p.id for p in rig.profiles]
    if any(i not in st.paths for i in ids):
        paths = curvenet.trace_profiles(engine_mesh(obj), rig)
        st.paths = dict(zip(ids, paths))
    return {i: st.paths[i] for i in ids}


# --- connect: embed and preview ---------------------------------------------


def connect(obj):
    """Embeds the object's rig in its mesh and shows the regions on a preview object.

    Returns (ok, report, message): the report is the CLI's, the message one
    line, "SUCCESS" or "FAILED" with the thesis's counts, or the engine's reason.
    """
    st = state(obj)
    st.error, st.failed_profile = "", ""
    rig = get_rig(obj)
    try:
        emb = curvenet.embed(engine_mesh(obj), rig)
    except curvenet.Error as e:
        st.report = None
        st.error = str(e)
        st.failed_profile = _named_profile(str(e), rig)
        return False, None, "FAILED: " + str(e)
    rep = emb.report
    st.report = rep
    st.paths = dict(emb.chains)
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
        st.error = "; ".join(rep["problems"])
        message += ": " + st.error
    return rep["ok"], rep, message


def _named_profile(message, rig):
    """The first profile an engine message names, to select it."""
    for p in rig.profiles:
        if "'%s'" % p.id in message:
            return p.id
    return ""


def make_preview(obj, emb):
    """A separate object with the cut mesh and one colour per region (and the
    CutChains as a curve object), parented to the mesh. The mesh itself is never edited."""
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
    me.update()
    preview = _attach(bpy.data.objects.new(name, me), obj)
    make_chains(obj, emb.chains)
    return preview


def make_chains(obj, chains):
    name = obj.name + CHAINS_SUFFIX
    _remove_object(name)
    cu = bpy.data.curves.new(name, "CURVE")
    cu.dimensions = "3D"
    cu.bevel_depth = 0.0015 * state(obj).diagonal
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
    return new


def _link_like(new, obj):
    cols = obj.users_collection or (bpy.context.scene.collection,)
    cols[0].objects.link(new)


# --- skeletons from armatures -----------------------------------------------


def armature_joints(obj, arm):
    """The armature's bones as joints in the mesh object's space, rest pose:
    bind = obj^-1 * arm * bone.matrix_local. Parents come first."""
    to_obj = obj.matrix_world.inverted() @ arm.matrix_world
    joints = []
    for bone in _bones_parents_first(arm):
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
        raise curvenet.InputError(obj.name, "/skeleton", "the rig has no skeleton to make an armature from")
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
    bones = [b.name for b in arm.data.bones if b.use_deform]
    return [b for b in bones if b in groups] if groups else bones


def starter(obj, arm, **options):
    """A starter net from the armature's bones (rest pose), set as the object's rig."""
    options.setdefault("deforming", deforming_bones(obj, arm))
    result = curvenet.starter(engine_mesh(obj), armature_joints(obj, arm), **options)
    set_rig(obj, result.rig)
    state(obj).paths.clear()
    return result


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


def bind(obj, arm, method=None, layer=None):
    """Binds the object's rig to the armature (its bones replace the rig's
    skeleton, matched by name), and starts live deformation. method:
    'dq', 'harmonic' or 'gradient' (docs/deform.md); by default the object's last.
    layer: keep the Armature modifier and layer the net over it, through a
    corrective shape key in rest space (docs/blender.md); by default the object's last."""
    joints = armature_joints(obj, arm)
    rig = get_rig(obj)
    rig = curvenet.with_skeleton(rig, joints, arm.name)
    set_rig(obj, rig)
    st = state(obj)
    method = method or obj.get(METHOD_KEY, "dq")
    layer = bool(obj.get(LAYER_KEY, False)) if layer is None else layer
    mod = armature_modifier(obj, arm)
    if layer and mod is None:
        raise curvenet.InputError(obj.name, "modifiers", "a layer sits on an Armature modifier: add one for " + arm.name)
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
    st.net_layer = None
    obj[METHOD_KEY] = method
    obj[LAYER_KEY] = layer
    names = {b.name for b in arm.data.bones}
    st.bone_names = [n if n in names else None for n in st.binding.joint_names]
    st.matrices = np.empty((len(st.bone_names), 4, 4), dtype=np.float64)
    st.positions = np.empty((st.binding.num_input_vertices, 3), dtype=np.float32)
    st.last_pose = None
    obj[ARMATURE_KEY] = arm.name
    _prepare_live(obj, keep_armature=layer)
    update_live(obj, force=True)
    return st.binding


def _prepare_live(obj, keep_armature=False):
    """A shape key over the basis receives the deformed positions; Armature
    modifiers on the object are switched off so the mesh is not moved twice.
    A layer keeps them: its shape key holds the rest position plus the
    correction, which the Armature modifier then moves."""
    me = obj.data
    if me.shape_keys is None:
        obj.shape_key_add(name="Basis", from_mix=False)
    key = me.shape_keys.key_blocks.get(SHAPE_KEY)
    if key is None:
        key = obj.shape_key_add(name=SHAPE_KEY, from_mix=False)
    key.value = 1.0
    key.slider_max = 1.0
    off = set(filter(None, obj.get(MODIFIERS_KEY, "").split("\n")))
    for mod in obj.modifiers:
        if keep_armature:
            break
        if mod.type == "ARMATURE" and (mod.show_viewport or mod.show_render):
            off.add(mod.name)
            mod.show_viewport = False
            mod.show_render = False
    obj[MODIFIERS_KEY] = "\n".join(sorted(off))


def unbind(obj):
    """Stops live deformation: removes the shape key, restores the Armature modifiers."""
    st = state(obj)
    st.binding = None
    st.layer = None
    st.net_layer = None
    if ARMATURE_KEY in obj:
        del obj[ARMATURE_KEY]
    me = obj.data
    if me.shape_keys is not None:
        key = me.shape_keys.key_blocks.get(SHAPE_KEY)
        if key is not None:
            obj.shape_key_remove(key)
    for name in filter(None, obj.get(MODIFIERS_KEY, "").split("\n")):
        mod = obj.modifiers.get(name)
        if mod is not None:
            mod.show_viewport = True
            mod.show_render = True
    if MODIFIERS_KEY in obj:
        del obj[MODIFIERS_KEY]


def bound_armature(obj):
    name = obj.get(ARMATURE_KEY)
    arm = bpy.data.objects.get(name) if name else None
    return arm if arm is not None and arm.type == "ARMATURE" else None


def ensure_binding(obj):
    """The object's binding, bound again (after a file load) if need be."""
    st = state(obj)
    if st.binding is None:
        arm = bound_armature(obj)
        if arm is None or not has_rig(obj):
            return None
        bind(obj, arm)
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
        raise curvenet.InputError(obj.name, node, "the node has no weights: bind first")
    return max(weights.items(), key=lambda kv: kv[1])[0]


def add_node_handle(obj, node):
    """An empty that pulls `node`: it rides on the node's heaviest bone, and
    moving it (or keying it on the timeline) gives the node an offset, which
    the curves through the node and the regions they bound follow."""
    arm = bound_armature(obj)
    if arm is None or ensure_binding(obj) is None:
        raise curvenet.InputError(obj.name, "binding", "bind the mesh to an armature first")
    rig = get_rig(obj)
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
    rig = get_rig(obj)
    to_obj = obj.matrix_world.inverted()
    out = {}
    for e in handles:
        node = e[HANDLE_KEY]
        if rig.node_index(node) < 0:
            continue
        source = e.evaluated_get(depsgraph) if depsgraph is not None else e
        p = to_obj @ source.matrix_world.translation
        j = st.bone_names.index(e.parent_bone) if e.parent_bone in st.bone_names else -1
        if j < 0:
            continue
        rest = np.linalg.solve(st.matrices[j], np.append(np.array(p), 1.0))[:3]
        offset = rest - rig.node(node).position
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


def live_objects():
    return [o for o in bpy.data.objects if o.type == "MESH" and ARMATURE_KEY in o and has_rig(o)]


def bake_vertex_groups(obj, arm, max_influences=4):
    """Bakes the binding to an ordinary skin: the top-k harmonic weights of
    each vertex as vertex groups named after the bones, and an Armature
    modifier on the armature. Live deformation stops; the mesh then plays
    with stock Blender, without the add-on. Returns the curvenet.SkinWeights."""
    binding = ensure_binding(obj)
    if binding is None or bound_armature(obj) != arm:
        bind(obj, arm)
        binding = state(obj).binding
    w = curvenet.bake_weights(binding, max_influences)
    unbind(obj)
    # Groups named after bones deform with them: those of another skin go.
    bones = {b.name for b in arm.data.bones}
    for vg in list(obj.vertex_groups):
        if vg.name in bones:
            obj.vertex_groups.remove(vg)
    groups = {}
    J, Wt = w.joint, w.weight
    for v in range(w.num_vertices):
        for i in range(w.influences):
            j = int(J[v, i])
            if j < 0:
                continue
            name = w.joints[j]
            vg = groups.get(name)
            if vg is None:
                vg = groups[name] = obj.vertex_groups.new(name=name)
            vg.add([v], float(Wt[v, i]), "REPLACE")
    mod = next((m for m in obj.modifiers if m.type == "ARMATURE"), None)
    if mod is None:
        mod = obj.modifiers.new("Armature", "ARMATURE")
    mod.object = arm
    mod.use_vertex_groups = True
    mod.use_bone_envelopes = False
    mod.use_deform_preserve_volume = False
    mod.show_viewport = mod.show_render = True
    return w


# --- node weights -----------------------------------------------------------


def set_node_weight(obj, nodes, bone, weight):
    """Sets the weight of `bone` on each node, scaling the node's other joints
    so that the weights still sum to 1 (the thesis's sparse editor). Nodes
    without weights start from their automatic ones. Binds again when bound."""
    if not 0.0 <= weight <= 1.0 or math.isnan(weight):
        raise ValueError("weight: expected a number in [0, 1]")
    rig = get_rig(obj)
    if not rig.has_skeleton:
        raise curvenet.InputError(obj.name, "/skeleton", "the rig has no skeleton yet: bind it or make a starter net")
    if bone not in {j.name for j in rig.joints}:
        raise curvenet.InputError(obj.name, bone, "the rig's skeleton has no joint of this name")
    complete = curvenet.complete_weights(rig)
    for node in nodes:
        if rig.node_index(node) < 0:
            raise KeyError("no node '%s'" % node)
        w = dict(complete.weights[node]) if node in complete.weights else {}
        others = {j: v for j, v in w.items() if j != bone and v > 0}
        total = sum(others.values())
        new = {bone: weight} if weight > 0 else {}
        if total > 0:
            for j, v in others.items():
                new[j] = v / total * (1.0 - weight)
        elif weight < 1.0:
            new = {bone: 1.0}  # nothing else to give the rest to
        rig.weights[node] = new
    set_rig(obj, rig)
    arm = bound_armature(obj)
    if arm is not None and state(obj).binding is not None:
        bind(obj, arm)
    return rig


def node_weights(obj, node):
    """The node's weights as the binding uses them (given or automatic)."""
    st = state(obj)
    if st.binding is not None:
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
    state(obj).paths.clear()
    return rig


def bake_cache(obj, path, frame_start, frame_end, scene=None):
    """Writes the deformation of frames [start, end] as a PC2 cache and plays it
    with a Mesh Cache modifier, so the .blend plays without the add-on. Live
    deformation of the object stops."""
    scene = scene or bpy.context.scene
    if frame_end < frame_start:
        raise ValueError("the last frame comes before the first")
    binding = ensure_binding(obj)
    arm = bound_armature(obj)
    if binding is None or arm is None:
        raise curvenet.InputError(obj.name, "binding", "bind the mesh to an armature first")
    st = state(obj)
    M = np.empty((len(st.bone_names), 4, 4))
    current = scene.frame_current

    def pose(f):
        scene.frame_set(f)
        return skinning_matrices(obj, arm, M, bpy.context.evaluated_depsgraph_get())

    try:
        # The library's frame job: blocks of bounded memory, streamed to the cache.
        curvenet.animate_poses(binding, pose, frame_start, frame_end, path, fps=scene.render.fps)
    finally:
        scene.frame_set(current)
    unbind(obj)
    for mod in obj.modifiers:
        if mod.type == "MESH_CACHE" and mod.name == "curvenet":
            obj.modifiers.remove(mod)
    mod = obj.modifiers.new("curvenet", "MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = path
    # The cache holds object-space positions in Blender's own axes and vertex order.
    mod.forward_axis = "POS_Y"
    mod.up_axis = "POS_Z"
    mod.frame_start = frame_start
    mod.frame_scale = 1.0
    with bpy.context.temp_override(object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=mod.name, index=0)
    for m in obj.modifiers:
        if m.type == "ARMATURE":
            m.show_viewport = False
            m.show_render = False
