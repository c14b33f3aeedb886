"""The demo's Python step: the tube from `curvenet demo`, through the module.

    PYTHONPATH=build/python /usr/bin/python3 scripts/demo_python.py out/demo
"""

import os
import sys

import numpy as np

import curvenet

out = sys.argv[1] if len(sys.argv) > 1 else "out/demo"
mesh = curvenet.load_mesh(os.path.join(out, "tube_quads.obj"))
rig = curvenet.read_rig(os.path.join(out, "tube.cnrig.json"))
emb = curvenet.embed(mesh, rig)
r = emb.report
print("python: embed %s, %d/%s regions, %d cut faces" % (
    "SUCCESS" if r["ok"] else "FAILED", r["regions"], r["expected_regions"], r["cut_mesh"]["faces"]))
binding = curvenet.bind(mesh, rig)
# Bend the tube at its middle joint, in 24 steps up to 90 degrees about X.
frames = []
for k in range(24):
    half = np.radians(90.0 * (k + 1) / 24) / 2
    pose = {"mid": {"rotation": [np.cos(half), np.sin(half), 0.0, 0.0]}}
    frames.append(curvenet.skinning_matrices(binding, pose))
positions = binding.deform_frames(np.stack(frames))
curvenet.write_pc2(os.path.join(out, "tube_quads.python_bend.pc2"), positions, 0.0)
moved = np.linalg.norm(positions[-1] - positions[0], axis=1).max()
print("python: %d frames of %d vertices in tube_quads.python_bend.pc2; the tip moved %.3f" % (
    positions.shape[0], positions.shape[1], moved))
