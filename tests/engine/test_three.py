"""A real engine in the suite: three.js (npm package `three`, pinned by
scripts/test.sh) poses each baked skin with GLTFLoader, AnimationMixer and
SkinnedMesh.getVertexPosition, as a game or web engine plays it. The test
checks that it agrees with curvenet's own evaluation of the same file
(its glTF reader, its clip sampler, linear blend skinning) to 1e-6 of the
diagonal: for the hand with the example rig, CesiumMan with its starter net,
and a low-poly wolf with its starter net, plain and with helper joints
(bake --helpers), each clip at its start, middle and end; and the wolf's
helpers driven by the engine from their joints (curvenet_helpers.mjs), their
keys taken out, at every third key.

Run: test_three.py CLI DATA_DIR NODE_MODULES OUT_DIR (with the Python module on PYTHONPATH).
Exit 77 (skipped) when three.js or the shared data is missing.
"""

import json
import os
import subprocess
import sys

import numpy as np

import curvenet

cli, data, modules, out = sys.argv[1:5]
here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
if not os.path.isfile(os.path.join(modules, "three", "package.json")):
    print("three.js is not installed in %s (scripts/test.sh installs it)" % modules)
    sys.exit(77)
if not os.path.isdir(data):
    print("no shared data at " + data)
    sys.exit(77)
os.makedirs(out, exist_ok=True)


def run(*args):
    r = subprocess.run([cli, *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("%s failed: %s" % (" ".join(args[:2]), r.stderr))


def ours(glb, times):
    """curvenet's evaluation of the baked file: its own reader and LBS, in the file's vertex order."""
    skin = curvenet.load_skinned_mesh(glb)
    mesh = curvenet.load_mesh(glb)
    rest = mesh.vertices[mesh.input_to_welded]
    J, W = skin.vertex_joints, skin.vertex_weights
    frames = []
    for clip, t in times:
        M = skin.skinning_matrices(clip, t)
        h = np.hstack([rest, np.ones((len(rest), 1))])
        posed = np.zeros((len(rest), 3))
        for k in range(J.shape[1]):
            j = np.where(J[:, k] >= 0, J[:, k], 0)
            w = np.where(J[:, k] >= 0, W[:, k], 0.0)
            posed += w[:, None] * np.einsum("nij,nj->ni", M[j][:, :3, :], h)
        frames.append(posed)
    return np.array(frames), float(np.linalg.norm(rest.max(0) - rest.min(0)))


def check(name, glb, drive=False):
    """three.js against curvenet at each clip's start, middle and end; with `drive`, at its keys (24 per
    second), the helpers' own keys taken out and the helpers driven from their joints by curvenet_helpers.mjs."""
    skin = curvenet.load_skinned_mesh(glb)
    times = []
    for c in range(skin.num_clips):
        a, b = skin.clip_range(c)
        if drive:
            times += [(c, a + k / 24.0) for k in range(0, int(round((b - a) * 24)) + 1, 3)]
        else:
            times += [(c, a), (c, 0.5 * (a + b)), (c, b)]
    binary = os.path.join(out, name.replace(" ", "_") + ".three.bin")
    r = subprocess.run(["node", os.path.join(here, "three_pose.mjs"), modules, glb, json.dumps(times), binary]
                       + (["drive-helpers"] if drive else []), capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("%s: three.js failed: %s" % (name, r.stderr[-2000:]))
    info = json.loads(r.stdout.strip().splitlines()[-1])
    want, diag = ours(glb, times)
    got = np.fromfile(binary, dtype=np.float64).reshape(want.shape)
    err = float(np.abs(got - want).max()) / diag
    print("%s: three.js r170 poses %d vertices at %d times of %d clips within %.2e of the diagonal of curvenet's"
          % (name, info["vertices"], len(times), skin.num_clips, err), flush=True)
    if not err <= 1e-6:
        sys.exit("%s: three.js and curvenet disagree by %.3g of the diagonal" % (name, err))


hand = os.path.join(data, "xr_tools_hand")
run("bake", os.path.join(hand, "hand_l.gltf"), os.path.join(hand, "example", "hand_l.cnrig.json"),
    "-o", os.path.join(out, "hand.glb"), "--clip", os.path.join(hand, "hand_l_poses.glb"))
check("hand", os.path.join(out, "hand.glb"))
cesium = os.path.join(data, "cesium_man", "CesiumMan.glb")
run("starter", cesium, "-o", os.path.join(out, "cesium.cnrig.json"))
run("bake", cesium, os.path.join(out, "cesium.cnrig.json"), "-o", os.path.join(out, "cesium.glb"), "--clip", cesium)
check("CesiumMan", os.path.join(out, "cesium.glb"))
wolf = os.path.join(repo, "tests", "data", "quaternius", "Wolf_decimated.glb")
run("starter", wolf, "-o", os.path.join(out, "wolf.cnrig.json"))
run("bake", wolf, os.path.join(out, "wolf.cnrig.json"), "-o", os.path.join(out, "wolf.glb"), "--clip", wolf)
check("wolf", os.path.join(out, "wolf.glb"))
# With helper joints (bake --helpers): nodes the file keys half way between
# two joints, which the engine plays as any other joint of the skin.
run("bake", wolf, os.path.join(out, "wolf.cnrig.json"), "-o", os.path.join(out, "wolf_helpers.glb"), "--clip", wolf,
    "--weights", "fitted", "--helpers", "12")
helped = curvenet.load_skinned_mesh(os.path.join(out, "wolf_helpers.glb"))
plain = curvenet.load_skinned_mesh(os.path.join(out, "wolf.glb"))
if not len(helped.joints) > len(plain.joints):
    sys.exit("wolf with helpers: the baked skin has no helper joints")
check("wolf with %d helper joints" % (len(helped.joints) - len(plain.joints)),
      os.path.join(out, "wolf_helpers.glb"))
# An engine playing clips of its own drives the helpers itself: the clips'
# helper keys taken out, tests/engine/curvenet_helpers.mjs (the recipe of
# docs/bake.md) poses them from their two joints, and the skin lands where
# the file's keys put it.
check("wolf, helpers driven by the engine", os.path.join(out, "wolf_helpers.glb"), drive=True)
print("three.js agrees with curvenet on every baked file")
