"""Baked skins in stock Blender, headless:

1. the skinned glTF that `curvenet bake` writes, read by Blender's own glTF
   importer and posed by its armature through a clip, lands where our own
   linear blend skinning of the baked weights puts it;
2. "Bake to Vertex Groups" on a bound hand gives vertex groups and an
   Armature modifier that, with the add-on switched off, pose the mesh as our
   LBS of the same weights does;
and a Workbench picture of the baked glTF opened in Blender.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

import addon_support as t  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Quaternion  # noqa: E402

t.empty_scene()
t.enable_addon()
import curvenet  # noqa: E402
import curvenet_blender  # noqa: E402
from curvenet_blender import core  # noqa: E402

HAND = os.path.join(t.DATA, "xr_tools_hand")
source = os.path.join(HAND, "hand_l.gltf")
clips_file = os.path.join(HAND, "hand_l_poses.glb")

# --- 1. the glTF, through Blender's importer ------------------------------
binding = curvenet.bind(curvenet.load_mesh(source), curvenet.read_rig(os.path.join(HAND, "example", "hand_l.cnrig.json")))
weights = curvenet.bake_weights(binding, 4)
clips = curvenet.load_skinned_mesh(clips_file)
glb = os.path.join(t.OUT, "hand_baked.glb")
curvenet.write_file(glb, curvenet.skinned_glb(source, binding, weights, clips, clip_names=["Grip", "Pistol"]))
rest = binding.deform(np.stack([np.eye(4)] * len(binding.joints)))  # the file's own rest positions

meshes, arms = t.import_gltf(glb)
t.check(len(meshes) == 1 and len(arms) == 1, "the baked glTF imports as one mesh and one armature")
obj, arm = meshes[0], arms[0]
t.check(len(obj.data.vertices) == len(rest), "with the file's %d vertices" % len(rest))
t.check(obj.modifiers[0].type == "ARMATURE", "skinned by an Armature modifier")
groups = {g.name for g in obj.vertex_groups}
t.check(groups <= set(weights.joints), "its vertex groups are the skeleton's joints")


def blender_world(obj):
    """Evaluated positions in world space, turned back from Blender's Z-up to glTF's Y-up."""
    P = t.evaluated_positions(obj)
    W = np.array(obj.matrix_world)
    P = P @ W[:3, :3].T + W[:3, 3]
    return np.stack([P[:, 0], P[:, 2], -P[:, 1]], axis=1)


diag = curvenet.load_mesh(source).bbox_diagonal()
arm.animation_data.action = None  # the importer makes the first clip active
for pb in arm.pose.bones:
    pb.matrix_basis.identity()
at_rest = blender_world(obj)
t.check(np.abs(at_rest - rest).max() < 1e-5 * diag, "at rest it is the source mesh, vertex for vertex")
actions = {a.name.split("_")[0]: a for a in bpy.data.actions}
scene = bpy.context.scene
fps = scene.render.fps / scene.render.fps_base
for name in ("Grip", "Pistol"):
    action = next(a for a in bpy.data.actions if a.name.startswith(name))
    arm.animation_data.action = action
    c = clips.find_clip(name)
    t0, t1 = clips.clip_range(c)
    for key in range(0, int(round((t1 - t0) * 24)) + 1):
        time = t0 + key / 24.0  # the keys the bake wrote
        frame = time * fps + 1  # the importer puts time 0 at frame 1
        scene.frame_set(int(np.floor(frame)), subframe=float(frame - np.floor(frame)))
        got = blender_world(obj)
        want = curvenet.skin_positions(weights, rest, curvenet.clip_skinning_matrices(binding, clips, c, time))
        err = np.abs(got - want).max()
        t.check(err < 1e-4 * diag, "%s at %.3f s: Blender poses it as our LBS does (max %.2e of the diagonal)" % (
            name, time, err / diag))
t.render_workbench([obj], os.path.join(t.OUT, "hand_baked_glb.png"), colour="SINGLE", size=(640, 480))

# --- 1b. with helper joints (bake --helpers): Blender plays their keys ------
t.empty_scene()
helped = curvenet.fit_weights(binding, curvenet.training_poses(binding), 4, helpers=8)
t.check(len(helped.helpers) > 0 and len(helped.joints) == len(binding.joints) + len(helped.helpers),
        "fit_weights with helpers=8 adds %d helper joints after the rig's" % len(helped.helpers))
glb = os.path.join(t.OUT, "hand_baked_helpers.glb")
curvenet.write_file(glb, curvenet.skinned_glb(source, binding, helped, clips, clip_names=["Grip"]))
meshes, arms = t.import_gltf(glb)
obj, arm = meshes[0], arms[0]
t.check({b.name for b in arm.data.bones} >= set(helped.joints[len(binding.joints):]),
        "the helpers import as bones of the armature")
action = next(a for a in bpy.data.actions if a.name.startswith("Grip"))
arm.animation_data.action = action
c = clips.find_clip("Grip")
t0, t1 = clips.clip_range(c)
scene = bpy.context.scene  # empty_scene() made a new one
for key in sorted({0, int(round((t1 - t0) * 24))}):
    time = t0 + key / 24.0
    frame = time * fps + 1
    scene.frame_set(int(np.floor(frame)), subframe=float(frame - np.floor(frame)))
    got = blender_world(obj)
    want = curvenet.skin_positions(helped, rest, curvenet.clip_skinning_matrices(binding, clips, c, time))
    err = np.abs(got - want).max()
    t.check(err < 1e-4 * diag, "Grip at %.3f s with helpers: Blender poses it as our LBS with the helpers' matrices "
            "(max %.2e of the diagonal)" % (time, err / diag))

# --- 1c. game animals under an armature: the bake rests and walks as its source -----
# The wolf as shipped (four IK roots resting a third of a degree off its
# body's) rested at a hundredth of its size, on its back; a bake of a Blender
# re-export (whose inverse bind matrices hold the armature) rested turned a
# quarter turn. Each bake, imported by Blender, rests and walks where its
# source does in Blender.


def box(objects):
    P = np.concatenate([t.evaluated_positions(o) @ np.array(o.matrix_world)[:3, :3].T
                        + np.array(o.matrix_world)[:3, 3] for o in objects])
    return P.min(axis=0), P.max(axis=0)


def rest_and_walk(path, frame=6):
    t.empty_scene()
    meshes, arms = t.import_gltf(path)
    for a in arms:
        a.data.pose_position = "REST"
    bpy.context.view_layer.update()
    rest = box(meshes)
    for a in arms:
        a.data.pose_position = "POSE"
        a.animation_data.action = next(x for x in bpy.data.actions if "Walk" in x.name)
    bpy.context.scene.frame_set(frame)
    return rest, box(meshes)


for animal in (os.path.join(t.DATA, "quaternius", "Wolf.glb"),
               os.path.join(os.path.dirname(__file__), "..", "data", "quaternius", "Horse_decimated.glb")):
    skin = curvenet.load_skinned_mesh(animal)
    rig = curvenet.starter(curvenet.load_mesh(animal), animal).rig
    binding = curvenet.bind(curvenet.load_mesh(animal), rig)
    baked = os.path.join(t.OUT, "animal_baked.glb")
    walk = next(n for n in skin.clip_names if "Walk" in n)
    curvenet.write_file(baked, curvenet.skinned_glb(animal, binding, curvenet.bake_weights(binding, 4), skin,
                                                    clip_names=[walk]))
    (lo, hi), (wlo, whi) = rest_and_walk(animal)
    (blo, bhi), (bwlo, bwhi) = rest_and_walk(baked)
    size = np.linalg.norm(hi - lo)
    name = os.path.basename(animal)
    t.check(np.abs(blo - lo).max() < 2e-3 * size and np.abs(bhi - hi).max() < 2e-3 * size,
            "%s baked rests where the source rests in Blender: %s against %s" % (name, np.round(bhi - blo, 3),
                                                                             np.round(hi - lo, 3)))
    t.check(np.abs(bwlo - wlo).max() < 3e-2 * size and np.abs(bwhi - whi).max() < 3e-2 * size,
            "and walks where it walks: %s against %s" % (np.round(bwhi - bwlo, 3), np.round(whi - wlo, 3)))

# --- 2. bake to vertex groups on a bound hand -------------------------------

POSED = (("Index_Proximal_L", 70), ("Thumb_Proximal_L", -40), ("Wrist_L", 25))


def pose_bones(arm, posed=POSED):
    """Turns these bones about the same axis by these angles (degrees; 0 puts them back at rest)."""
    for name, angle in posed:
        pb = arm.pose.bones[name]
        pb.rotation_mode = "QUATERNION"
        pb.rotation_quaternion = Quaternion((1, 0, 0.3), np.radians(angle))
    bpy.context.view_layer.update()


def groups_as_weights(obj, names, helpers=()):
    """The mesh's vertex groups as curvenet.SkinWeights over `names` (the last len(helpers) of them helpers)."""
    at = {n: i for i, n in enumerate(names)}
    J = np.full((len(obj.data.vertices), 8), -1)
    Wt = np.zeros((len(obj.data.vertices), 8))
    for v in obj.data.vertices:
        for i, g in enumerate(v.groups):
            J[v.index, i] = at[obj.vertex_groups[g.group].name]
            Wt[v.index, i] = g.weight
    return curvenet.SkinWeights(names, J, Wt, list(helpers))


def armature_matrices(obj, arm, names):
    """The skinning matrices the Armature modifier uses, in the mesh object's space."""
    O, A = obj.matrix_world, arm.matrix_world
    return np.array([np.array(O.inverted() @ A @ arm.pose.bones[n].matrix
                              @ arm.pose.bones[n].bone.matrix_local.inverted() @ A.inverted() @ O) for n in names])


t.empty_scene()
t.enable_addon()
import curvenet_blender  # noqa: E402,F811
from curvenet_blender import core  # noqa: E402,F811

meshes, arms = t.import_gltf(source)
obj, arm = meshes[0], arms[0]
t.select(obj, arm)
bpy.ops.curvenet.import_rig(filepath=os.path.join(HAND, "example", "hand_l.cnrig.json"))
rig_file = curvenet.read_rig(os.path.join(HAND, "example", "hand_l.cnrig.json"))
ours = core.get_rig(obj)
t.check(np.allclose(ours.nodes[0].position, core.Y_UP_TO_BLENDER[:3, :3] @ rig_file.nodes[0].position),
        "a rig made on the glTF file is turned into the object's Z-up space on import")
back = os.path.join(t.OUT, "hand_yup.cnrig.json")
t.check(bpy.ops.curvenet.export_rig(filepath=back, up="Y") == {"FINISHED"}, "export in the glTF file's space")
again = curvenet.read_rig(back)
t.check(max(np.abs(a.position - b.position).max() for a, b in zip(again.nodes, rig_file.nodes)) < 1e-12,
        "and it comes back as the file was")
t.check(bpy.ops.curvenet.bind() == {"FINISHED"}, "bound")
# Fitted weights first: the groups are the Python module's fit over the skeleton's own poses.
t.check(bpy.ops.curvenet.bake_vertex_groups(max_influences=4, weights="FITTED") == {"FINISHED"},
        bpy.context.scene.curvenet.status)
binding = core.ensure_binding(obj)
fit = curvenet.fit_weights(binding, curvenet.training_poses(binding), 4)
group_weight = {}
for v in obj.data.vertices:
    for g in v.groups:
        group_weight[(v.index, obj.vertex_groups[g.group].name)] = g.weight
want_fit = {(v, fit.joints[int(fit.joint[v, i])]): float(fit.weight[v, i])
            for v in range(fit.num_vertices) for i in range(fit.influences) if fit.joint[v, i] >= 0}
t.check(bpy.context.scene.curvenet.status.startswith("Vertex groups (fitted weights)"),
        "the status names the weights baked: " + bpy.context.scene.curvenet.status)
t.check(group_weight.keys() == want_fit.keys()
        and max(abs(group_weight[k] - want_fit[k]) for k in want_fit) < 1e-6,
        "Bake to Vertex Groups, fitted: the groups are fit_weights over training_poses")
# With helper bones: each half way between two bones, posed by an Armature
# constraint with Preserve Volume, so stock Blender plays the fitted skin.
rig_bones = [b.name for b in arm.data.bones]
t.check(bpy.ops.curvenet.bake_vertex_groups(max_influences=4, weights="FITTED", helpers=8) == {"FINISHED"},
        bpy.context.scene.curvenet.status)
helped = curvenet.fit_weights(binding, curvenet.training_poses(binding), 4, helpers=8)
helper_names = helped.joints[len(helped.joints) - len(helped.helpers):]
t.check(len(helper_names) > 0 and all(n in arm.data.bones and arm.data.bones[n].parent is None for n in helper_names),
        "Bake to Vertex Groups with Helper Bones 8: %d helper bones, without parents" % len(helper_names))
t.check(all(list(arm.data.bones[n].layers) == [i == core.HELPER_LAYER for i in range(32)] for n in helper_names),
        "on their own bone layer, out of the way of the rig's")
for n, (a, b) in zip(helper_names, helped.helpers):
    c = arm.pose.bones[n].constraints[0]
    t.check(c.type == "ARMATURE" and c.use_deform_preserve_volume
            and sorted((x.subtarget, x.weight) for x in c.targets) == sorted([(helped.joints[a], 0.5),
                                                                               (helped.joints[b], 0.5)]),
            "%s: an Armature constraint on its two bones, half each, Preserve Volume" % n)
t.check("helper bones" in bpy.context.scene.curvenet.status, "the status says so: " + bpy.context.scene.curvenet.status)
try:
    bpy.ops.curvenet.bake_vertex_groups(max_influences=4, weights="HARMONIC", helpers=8)
    refusal = ""
except RuntimeError as e:  # an operator's error report, raised in a script
    refusal = str(e)
t.check("choose Fitted weights" in refusal, "helper bones with harmonic weights are refused: " + refusal)
t.check(all(n in arm.data.bones for n in helper_names), "and the refusal leaves the bake as it was")
rest_h = np.array([v.co[:] for v in obj.data.vertices])
pose_bones(arm)
got = t.evaluated_positions(obj)
index = {n: i for i, n in enumerate(rig_bones)}
pairs = [(index[helped.joints[a]], index[helped.joints[b]]) for a, b in helped.helpers]
w_h = groups_as_weights(obj, rig_bones + helper_names, pairs)
err = np.abs(got - curvenet.skin_positions(w_h, rest_h, armature_matrices(obj, arm, rig_bones))).max()
t.check(err < 1e-5 * diag, "the Armature modifier with the helper bones' constraints poses it as our LBS with "
        "helper_matrix (max %.2e of the diagonal)" % (err / diag))
pose_bones(arm, [(name, 0) for name, _ in POSED])
t.check(bpy.ops.curvenet.bake_vertex_groups(max_influences=4) == {"FINISHED"}, bpy.context.scene.curvenet.status)
t.check(not any(n in arm.data.bones for n in helper_names), "baking again without helpers removes the helper bones")
t.check(obj.data.shape_keys is None or obj.data.shape_keys.key_blocks.get(core.SHAPE_KEY) is None,
        "live deformation is off")
mod = [m for m in obj.modifiers if m.type == "ARMATURE"]
t.check(len(mod) == 1 and mod[0].object == arm and mod[0].show_viewport, "one Armature modifier, on the armature")
rest_b = np.array([v.co[:] for v in obj.data.vertices])
baked = curvenet.SkinWeights  # the weights the operator wrote, read back from the groups
names = [b.name for b in arm.data.bones]
curvenet_blender.unregister()  # stock Blender from here
pose_bones(arm)
got = t.evaluated_positions(obj)
# Our LBS of the same weights, with the matrices the Armature modifier uses.
w = groups_as_weights(obj, names)
Wt = w.weight
M = armature_matrices(obj, arm, names)
want = curvenet.skin_positions(w, rest_b, M)
err = np.abs(got - want).max()
t.check(np.abs(got - rest_b).max() > 0.005, "the bones move the mesh")
t.check(err < 1e-5 * diag, "the Armature modifier poses it as our LBS of the baked weights (max %.2e)" % err)
t.check(np.allclose(Wt.sum(axis=1), 1, atol=1e-6), "each vertex's group weights sum to 1")
print("CURVENET_TEST all passed")
