"""The Python module, as a specification: what each call takes and gives,
and that it gives exactly what the CLI gives on the shared hand.

Run by ctest (tests/CMakeLists.txt) with PYTHONPATH=build/python,
CURVENET_CLI and CURVENET_DATA_DIR set.
"""

import ast
import json
import os
import re
import struct
import subprocess
import sys
import threading
import time
import warnings

import numpy as np
import pytest

import curvenet

DATA = os.environ.get("CURVENET_DATA_DIR", os.path.join(os.path.dirname(__file__), "../../../shared/data"))
CLI = os.environ.get("CURVENET_CLI", "build/bin/curvenet")
HAND = os.path.join(DATA, "xr_tools_hand")
needs_data = pytest.mark.skipif(not os.path.isdir(HAND), reason="no shared data")


def hand(name="hand_l.gltf"):
    return os.path.join(HAND, name)


def example(name):
    return os.path.join(HAND, "example", name)


def cli(*args):
    run = subprocess.run([CLI, *args], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return run.stdout


def read_obj_vertices(path):
    with open(path) as f:
        return np.array([[float(x) for x in line.split()[1:4]] for line in f if line.startswith("v ")])


def read_pc2(path):
    with open(path, "rb") as f:
        head = f.read(32)
        sig, version, points, start, rate, frames = struct.unpack("<12siiffi", head)
        assert sig == b"POINTCACHE2\0"
        data = np.frombuffer(f.read(), dtype="<f4")
    return data.reshape(frames, points, 3), start


def tetrahedron():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    return V, F


# --- meshes -----------------------------------------------------------------


def test_a_mesh_from_arrays_takes_triangles_quads_or_polygons():
    V, F = tetrahedron()
    m = curvenet.Mesh(V, F)
    assert (m.num_vertices, m.num_faces, m.num_input_vertices) == (4, 4, 4)
    np.testing.assert_array_equal(m.vertices, V)
    cube_v = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    quads = np.array([[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])
    cube = curvenet.Mesh(cube_v, quads)
    assert cube.num_faces == 6 and list(cube.face_offsets) == [0, 4, 8, 12, 16, 20, 24]
    # A list of polygons of mixed sizes: one quad split into two triangles.
    mixed = [list(q) for q in quads[1:]] + [[0, 2, 3], [0, 3, 1]]
    assert curvenet.Mesh(cube_v, mixed).num_faces == 7


def test_a_bad_mesh_raises_input_error_naming_the_source_and_element():
    V, F = tetrahedron()
    with pytest.raises(curvenet.InputError) as e:
        curvenet.Mesh(V, [[0, 1, 9]], source="mine")
    assert e.value.file == "mine" and e.value.element == "index 9"
    bad = V.copy()
    bad[2, 1] = np.nan
    with pytest.raises(curvenet.InputError) as e:
        curvenet.Mesh(bad, F)
    assert "vertex 2" in e.value.element
    with pytest.raises(ValueError):
        curvenet.Mesh(V[:, :2], F)
    with pytest.raises(curvenet.InputError) as e:
        curvenet.load_mesh("/no/such/mesh.obj")
    assert e.value.file == "/no/such/mesh.obj"
    assert isinstance(e.value, curvenet.Error) and isinstance(e.value, RuntimeError)


# --- rigs -------------------------------------------------------------------


@needs_data
def test_a_rig_is_edited_in_place_and_written_back(tmp_path):
    rig = curvenet.read_rig(example("hand_l.cnrig.json"))
    n = len(rig.nodes)
    node = rig.nodes[0]
    before = node.position.copy()
    node.position[1] += 0.001  # a view into the rig
    np.testing.assert_allclose(rig.nodes[0].position, before + [0, 0.001, 0])
    rig.add_node("extra", [0.01, 0.02, 0.03])
    rig.profiles.append(curvenet.Profile("p_extra", rig.nodes[0].id, "extra"))
    rig.weights["extra"] = {rig.joints[0].name: 1.0}
    mid = (rig.nodes[0].position + [0.01, 0.02, 0.03]) / 2
    rig.profile("p_extra").curve = curvenet.Curve(np.array([rig.nodes[0].position, mid, [0.01, 0.02, 0.03]]))
    # A profile naming a node that does not exist is refused before anything is written.
    broken = rig.copy()
    broken.profiles.append(curvenet.Profile("p_bad", "extra", "nowhere", curvenet.Curve(np.zeros((2, 3)))))
    with pytest.raises(curvenet.InputError) as e:
        curvenet.write_rig(broken, str(tmp_path / "broken.cnrig.json"))
    assert e.value.element.endswith("/to")
    assert not (tmp_path / "broken.cnrig.json").exists()
    with pytest.raises(curvenet.InputError):
        curvenet.embed(curvenet.load_mesh(hand()), broken)
    out = tmp_path / "edited.cnrig.json"
    curvenet.write_rig(rig, str(out))
    back = curvenet.read_rig(str(out))
    assert len(back.nodes) == n + 1 and back.node_index("extra") == n
    np.testing.assert_array_equal(back.node("extra").position, [0.01, 0.02, 0.03])
    assert back.profile("p_extra").from_ == rig.nodes[0].id
    assert dict(back.weights["extra"]) == {rig.joints[0].name: 1.0}
    np.testing.assert_array_equal(back.nodes[0].position, rig.nodes[0].position)
    assert back.to_json() == rig.to_json()
    with pytest.raises(KeyError):
        rig.node("nope")


def test_a_damaged_rig_names_its_json_path(tmp_path):
    bad = tmp_path / "bad.cnrig.json"
    bad.write_text('{"format": "curvenet-rig", "version": 1, "nodes": [{"id": 3}]}')
    with pytest.raises(curvenet.InputError) as e:
        curvenet.read_rig(str(bad))
    assert e.value.file == str(bad)
    assert e.value.element.startswith("/nodes/0")
    assert not (tmp_path / "out.cnrig.json").exists()


# --- embedding --------------------------------------------------------------


@needs_data
def test_the_report_has_the_cli_keys_and_values(tmp_path):
    report = tmp_path / "r.json"
    cli("embed", hand(), example("hand_l.cnrig.json"), "--report", str(report))
    want = json.loads(report.read_text())
    e = curvenet.embed(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    got = e.report
    assert set(got) == set(want)
    for key in want:
        if key != "timings_ms":
            assert got[key] == want[key], key
    assert e.ok and got["regions"] == 47


@needs_data
def test_the_cut_mesh_and_chains_come_as_arrays():
    m = curvenet.load_mesh(hand())
    rig = curvenet.read_rig(example("hand_l.cnrig.json"))
    e = curvenet.embed(m, rig)
    V, offsets, corners = e.cut_mesh()
    nv, nf = e.report["cut_mesh"]["vertices"], e.report["cut_mesh"]["faces"]
    assert V.shape == (nv, 3)
    assert len(offsets) == nf + 1 and offsets[-1] == len(corners)
    assert e.face_regions.shape == (nf,)
    assert set(e.face_regions) == set(range(47))
    assert e.face_colours.shape == (nf, 3)
    assert list(e.chains) == [p.id for p in rig.profiles]
    # Every chain point is a cut-mesh vertex.
    for pts in e.chains.values():
        d = np.min(np.linalg.norm(V[None, :, :] - pts[:, None, :], axis=2), axis=1)
        assert d.max() == 0.0
    # The traced paths are what the cut follows: same ends as the chains.
    paths = curvenet.trace_profiles(m, rig)
    assert len(paths) == len(rig.profiles)
    tol = e.report["fidelity"]["tolerance"]
    for path, pts in zip(paths, e.chains.values()):
        assert np.linalg.norm(path[0] - pts[0]) < tol and np.linalg.norm(path[-1] - pts[-1]) < tol


@needs_data
def test_progress_is_reported_and_its_errors_are_raised():
    m = curvenet.load_mesh(hand())
    rig = curvenet.read_rig(example("hand_l.cnrig.json"))
    seen = []
    curvenet.embed(m, rig, progress=lambda stage, f: seen.append((stage, f)))
    assert ("trace", 1.0) in seen

    def fail(stage, f):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        curvenet.embed(m, rig, progress=fail)


def test_crossing_profiles_raise_embed_error():
    # Two straight profiles across a square's diagonals cross in the middle.
    n = 8
    V = np.array([[x / n, y / n, 0.0] for y in range(n + 1) for x in range(n + 1)])
    F = [[y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x]
         for y in range(n) for x in range(n)]
    m = curvenet.Mesh(V, F)
    rig = curvenet.Rig()
    rig.coverage = "local"
    for name, p in [("a", [0.1, 0.1, 0]), ("b", [0.9, 0.9, 0]), ("c", [0.9, 0.1, 0]), ("d", [0.1, 0.9, 0])]:
        rig.add_node(name, p)
    rig.add_profile("ab", "a", "b")
    rig.add_profile("cd", "c", "d")
    with pytest.raises(curvenet.EmbedError) as e:
        curvenet.embed(m, rig)
    assert "'ab'" in str(e.value) and "'cd'" in str(e.value)


# --- binding and deformation ------------------------------------------------


@needs_data
def test_deform_gives_exactly_the_cli_pose_output(tmp_path):
    out = tmp_path / "fist.obj"
    cli("pose", hand(), example("hand_l.cnrig.json"), example("fist.pose.json"), "-o", str(out))
    b = curvenet.bind(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    M = curvenet.skinning_matrices(b, example("fist.pose.json"))
    assert M.shape == (len(b.joints), 4, 4)
    P = b.deform(M)
    want = read_obj_vertices(out)  # 17 significant digits read back exactly
    assert P.shape == want.shape == (b.num_input_vertices, 3)
    assert np.array_equal(P, want)  # bit for bit
    # The same pose given as a dict, and as JointPose entries.
    with open(example("fist.pose.json")) as f:
        entries = json.load(f)["joints"]
    assert np.array_equal(curvenet.skinning_matrices(b, entries), M)
    poses = curvenet.read_pose(example("fist.pose.json"))
    assert np.array_equal(curvenet.skinning_matrices(b, poses), M)


@needs_data
def test_deform_frames_gives_exactly_the_cli_animation(tmp_path):
    clips_file = hand("hand_l_poses.glb")
    mesh_file = example("hand_l_welded.obj")
    pc2 = tmp_path / "grip.pc2"
    cli("animate", mesh_file, example("hand_l.cnrig.json"), clips_file, "--clip", "Grip", "-o", str(pc2))
    want, start = read_pc2(pc2)
    b = curvenet.bind(curvenet.load_mesh(mesh_file), curvenet.read_rig(example("hand_l.cnrig.json")))
    clips = curvenet.load_skinned_mesh(clips_file)
    clip = clips.find_clip("Grip")
    first, last = curvenet.clip_frames(clips, clip, 24.0)
    assert first == start and last - first + 1 == want.shape[0]
    M = np.stack([curvenet.clip_skinning_matrices(b, clips, clip, f / 24.0) for f in range(first, last + 1)])
    P = b.deform_frames(M)
    assert P.shape == want.shape
    assert np.array_equal(P.astype(np.float32), want)  # the cache holds float32
    for f in range(P.shape[0]):
        assert np.array_equal(P[f], b.deform(M[f]))
    # write_pc2 writes the same cache.
    mine = tmp_path / "mine.pc2"
    curvenet.write_pc2(str(mine), P, first)
    assert mine.read_bytes() == pc2.read_bytes()
    # The library's animation job, which the CLI runs, streams the same cache.
    streamed = tmp_path / "streamed.pc2"
    assert curvenet.animate(b, clips, clip, str(streamed)) == (first, last)
    assert streamed.read_bytes() == pc2.read_bytes()
    # A range of frames, checked as the CLI checks --frames (past the
    # clip's end, its last key holds).
    part = tmp_path / "part.pc2"
    assert curvenet.animate(b, clips, clip, str(part), frames=f"{first}:{first + 2}") == (first, first + 2)
    got, start = read_pc2(part)
    assert start == first and got.shape[0] == 3 and np.array_equal(got[0], want[0])
    with pytest.raises(curvenet.InputError, match="--frames"):
        curvenet.animate(b, clips, clip, str(part), frames="2:1")


@needs_data
def test_animating_with_a_clip_file_of_another_skeleton_warns_as_the_cli_notes(tmp_path):
    # The T-rex's rig against its own clips says nothing; against a skeleton
    # whose bones are a hundredth as long (a file in other units) each
    # animate warns with the line `curvenet animate` prints as a note.
    trex = os.path.join(DATA, "quaternius", "Trex.glb")
    mesh, clips = curvenet.load_mesh(trex), curvenet.load_skinned_mesh(trex)
    rig = curvenet.starter(mesh, clips).rig
    clip = clips.find_clip("TRex_Walk")
    assert curvenet.clip_notes(rig, clips) == []
    b = curvenet.bind(mesh, rig)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none at all
        curvenet.animate(b, clips, clip, str(tmp_path / "own.pc2"), frames="0:1")
    for i in range(len(rig.joints)):
        rig.joints[i].bind[:3, 3] *= 0.01  # a writable view
    notes = curvenet.clip_notes(rig, clips)
    # The file's armature scales its skeleton, whose root keys carry that
    # scale, and the rig's is the file's scaled as a whole: said first; then
    # the bones a hundredth as long.
    assert len(notes) == 2, notes
    assert "Trex.glb: its armature scales its skeleton by" in notes[0] and "a second time" in notes[0], notes
    assert "Trex.glb: its skeleton is not the rig's (joint '" in notes[1], notes
    assert "rests 100 times as far from its parent" in notes[1]
    b = curvenet.bind(mesh, rig)
    with pytest.warns(UserWarning) as caught:
        curvenet.animate(b, clips, clip, str(tmp_path / "other.pc2"), frames="0:1")
    assert [str(w.message) for w in caught] == notes
    # Turned into errors, the warning stops the run before anything is written.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning):
            curvenet.animate(b, clips, clip, str(tmp_path / "none.pc2"), frames="0:1")
    assert not (tmp_path / "none.pc2").exists()


@needs_data
def test_bake_from_python_is_the_clis_bake_to_the_byte_and_reports_what_it_prints(tmp_path):
    mesh, rig, clips = hand(), example("hand_l.cnrig.json"), hand("hand_l_poses.glb")
    out = cli("bake", mesh, rig, "-o", str(tmp_path / "cli.glb"), "--clip", clips, "--clip-name", "Grip",
              "--clip-name", "OK", "--weights", "fitted")
    r = curvenet.bake(mesh, rig, output=str(tmp_path / "py.glb"), weights_csv=str(tmp_path / "py.csv"),
                      clip_file=clips, clip_names=["Grip", "OK"], weights="fitted")
    assert (tmp_path / "py.glb").read_bytes() == (tmp_path / "cli.glb").read_bytes()
    assert (tmp_path / "py.csv").read_text().count("\n") == r["vertices"] + 1  # a header and a row per vertex
    assert r["clips"] == 2 and r["training_poses"] > 0 and r["influences"] == 4
    assert [f["clip"] for f in r["fidelity"]] == sorted(["Grip", "OK"], key=lambda c: -next(
        f["max"] for f in r["fidelity"] if f["clip"] == c))
    for f in r["fidelity"]:
        # The numbers the CLI printed for that clip, to its two decimals.
        line = next(l for l in out.splitlines() if l.startswith(f"  clip '{f['clip']}'"))
        assert f" mean {100 * f['mean']:.2f}, max {100 * f['max']:.2f} at vertex {f['worst_vertex']} " in line, line
        assert f"; floor {100 * f['worst_floor']:.2f} (no linear skin of the {f['worst_joints']} rig joints" in line
        assert 0 <= f["worst_floor"] <= f["max"]
    # Layered over the file's own skin and fitted to it, as `bake --over-skin --fit`.
    cli("bake", mesh, rig, "--weights-csv", str(tmp_path / "cli_layer.csv"), "--over-skin", "--fit", clips,
        "--envelope", "0.5")
    r = curvenet.bake(mesh, rig, weights_csv=str(tmp_path / "py_layer.csv"), over_skin=True, fit=clips, envelope=0.5)
    assert (tmp_path / "py_layer.csv").read_bytes() == (tmp_path / "cli_layer.csv").read_bytes()
    # With helper joints, as `bake --helpers`.
    cli("bake", mesh, rig, "-o", str(tmp_path / "cli_helpers.glb"), "--weights", "fitted", "--helpers", "4")
    r = curvenet.bake(mesh, rig, output=str(tmp_path / "py_helpers.glb"), weights="fitted", helpers=4)
    assert (tmp_path / "py_helpers.glb").read_bytes() == (tmp_path / "cli_helpers.glb").read_bytes()
    assert r["helpers"] == 4 and len(r["helper_joints"]) == 4 and all("~" in n for n in r["helper_joints"])
    assert "helpers: " + ", ".join(r["helper_joints"]) in cli("bake", mesh, rig, "-o", str(tmp_path / "again.glb"),
                                                               "--weights", "fitted", "--helpers", "4")
    # Bad input: one error naming the element, nothing written.
    with pytest.raises(curvenet.InputError, match="helpers"):
        curvenet.bake(mesh, rig, output=str(tmp_path / "bad.glb"), helpers=4)  # harmonic weights are not fitted
    with pytest.raises(curvenet.InputError, match="max influences"):
        curvenet.bake(mesh, rig, output=str(tmp_path / "bad.glb"), max_influences=9)
    with pytest.raises(ValueError, match="weights"):
        curvenet.bake(mesh, rig, output=str(tmp_path / "bad.glb"), weights="best")
    with pytest.raises(ValueError, match="output"):
        curvenet.bake(mesh, rig)
    assert not (tmp_path / "bad.glb").exists()


@needs_data
def test_deform_into_a_given_buffer_and_checks_its_input():
    b = curvenet.bind(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    M = curvenet.skinning_matrices(b, example("fist.pose.json"))
    P = b.deform(M)
    buf64 = np.empty((b.num_input_vertices, 3))
    buf32 = np.empty((b.num_input_vertices, 3), np.float32)
    assert b.deform(M, out=buf64) is buf64 and np.array_equal(buf64, P)
    b.deform(M, out=buf32)
    assert np.array_equal(buf32, P.astype(np.float32))
    rest = b.deform(np.stack([np.eye(4)] * len(b.joints)))
    np.testing.assert_allclose(rest, b.deform(curvenet.skinning_matrices(b, {})), atol=0)
    with pytest.raises(ValueError):
        b.deform(M[:-1])
    with pytest.raises(ValueError):
        b.deform(M, out=np.empty((3, 3)))
    bad = M.copy()
    bad[3, 0, 0] = np.inf
    with pytest.raises(curvenet.InputError) as e:
        b.deform(bad)
    assert e.value.element == "matrix 3"
    with pytest.raises(curvenet.InputError):
        curvenet.skinning_matrices(b, {"NoSuchJoint": {"rotation": [1, 0, 0, 0]}})
    with pytest.raises(curvenet.InputError) as e:
        curvenet.skinning_matrices(b, {rig_joint(b): {"rotation": [2, 0, 0, 0]}})
    assert "rotation" in e.value.element


def rig_joint(b):
    return b.joint_names[0]


@needs_data
def test_deform_frames_runs_without_the_gil():
    # While one thread is inside deform_frames, another runs Python: it can
    # only if the call released the GIL. The gradient mode makes each frame
    # long enough to see (about 1 ms on the hand).
    b = curvenet.bind(curvenet.load_mesh(example("hand_l_welded.obj")), curvenet.read_rig(example("hand_l.cnrig.json")),
                      method="gradient")
    clips = curvenet.load_skinned_mesh(hand("hand_l_poses.glb"))
    poses = np.stack([curvenet.clip_skinning_matrices(b, clips, c, 0.0) for c in range(clips.num_clips)])
    M = np.concatenate([poses] * 8)  # 280 frames
    window = {}
    started = threading.Event()

    def work():
        started.set()
        window["enter"] = time.perf_counter()
        window["result"] = b.deform_frames(M)
        window["exit"] = time.perf_counter()

    old = sys.getswitchinterval()
    sys.setswitchinterval(0.001)
    try:
        worker = threading.Thread(target=work)
        worker.start()
        started.wait()
        ticks = []
        while worker.is_alive():
            ticks.append(time.perf_counter())
        worker.join()
    finally:
        sys.setswitchinterval(old)
    t0, t1 = window["enter"], window["exit"]
    inside = [t for t in ticks if t0 < t < t1]
    covered = sum(min(b_ - a_, 1e-3) for a_, b_ in zip(inside, inside[1:]))
    assert covered > 0.25 * (t1 - t0), "Python ran %.1f ms of the call's %.1f ms" % (1e3 * covered, 1e3 * (t1 - t0))
    # And the frames are what deform gives, one by one.
    for f in (0, 100, 279):
        assert np.array_equal(window["result"][f], b.deform(M[f]))


@needs_data
def test_bind_options_and_weights(tmp_path):
    m = curvenet.load_mesh(hand())
    rig = curvenet.read_rig(example("hand_l.cnrig.json"))
    b = curvenet.bind(m, rig)
    assert b.has_embedding and b.embedding.ok
    assert b.report["vertices"] == m.num_vertices and b.report["mean_influences"] > 1
    for node, w in b.node_weights.items():
        assert abs(sum(w.values()) - 1) < 1e-9, node
    bare = rig.copy()
    for node in list(bare.weights.keys()):
        del bare.weights[node]
    full = curvenet.complete_weights(bare)
    assert len(full.weights) == len(rig.nodes)
    cache = tmp_path / "hand.cnbind"
    c1 = curvenet.bind(m, rig, cache=str(cache))
    c2 = curvenet.bind(m, rig, cache=str(cache))
    assert cache.exists() and not c2.has_embedding
    M = curvenet.skinning_matrices(b, example("fist.pose.json"))
    assert np.array_equal(c1.deform(M), c2.deform(M))
    with pytest.raises(ValueError):
        curvenet.bind(m, rig, laplacian="cotan")
    no_skeleton = rig.copy()
    no_skeleton.has_skeleton = False
    no_skeleton.joints = []
    with pytest.raises(curvenet.InputError):
        curvenet.bind(m, no_skeleton)


# --- starter, transfer, compare, subdivide ---------------------------------


@needs_data
def test_starter_transfer_and_compare_on_the_hand():
    m = curvenet.load_mesh(hand())
    low = curvenet.load_mesh(hand("Hand_low_L.gltf"))
    s = curvenet.starter(m, hand())
    assert s.rings >= 20 and s.net_components == 1 and s.rig.has_skeleton
    # the joints without a ring, with their reasons: the palm's metacarpals and its leaf
    assert s.ringless and all(j.endswith("_Metacarpal_L") or j == "Palm_L" for j, _ in s.ringless)
    assert all(why for _, why in s.ringless)
    assert curvenet.embed(m, s.rig).ok
    # the file's skin weights the nodes by default, read from the file or given as a SkinnedMesh
    assert curvenet.starter(m, curvenet.load_skinned_mesh(hand())).rig.to_json() == s.rig.to_json()
    assert curvenet.starter(m, hand(), weight_rule="skin").rig.to_json() == s.rig.to_json()
    # bare joints have no skin: the bones' rule weights them, and asking for the skin is an error
    by_rule = curvenet.starter(m, curvenet.load_skeleton(hand()))
    assert by_rule.rig.to_json() != s.rig.to_json()
    assert curvenet.starter(m, hand(), weight_rule="blend-zone").rig.to_json() == by_rule.rig.to_json()
    with pytest.raises(ValueError):
        curvenet.starter(m, curvenet.load_skeleton(hand()), weight_rule="skin")
    t = curvenet.transfer(s.rig, m, low)
    assert t.ok and t.agreement > 0.99
    assert t.report["target"]["regions"] == t.report["source"]["regions"]
    d = curvenet.compare(m, low)
    assert set(d) >= {"a_to_b", "b_to_a", "mean", "rms", "max", "diagonal", "mean_percent"}
    assert 0 < d["mean_percent"] < 1


@needs_data
def test_a_skeleton_loaded_for_a_mesh_is_placed_as_the_clis_skeleton_option_places_it():
    # Blender's re-export of the horse is in its scene's space (100 times
    # the skin's size, Y up). load_skeleton(path) gives the horse's joints
    # as bound, a hundredth of that mesh's size; load_skeleton(path, mesh)
    # places them for the mesh as `--skeleton` does, and warns with the
    # CLI's note. For the horse's own mesh, the joints as bound, silently.
    horse = os.path.join(DATA, "quaternius", "Horse.glb")
    again = os.path.join(os.path.dirname(__file__), "..", "data", "quaternius", "Horse_decimated.glb")
    bound = curvenet.load_skeleton(horse)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none for its own mesh
        own = curvenet.load_skeleton(horse, curvenet.load_mesh(horse))
    assert [j.name for j in own] == [j.name for j in bound]
    assert all(np.array_equal(a.bind, b.bind) for a, b in zip(own, bound))
    again_mesh = curvenet.load_mesh(again)
    with pytest.warns(UserWarning, match="taken as placed"):
        placed = curvenet.load_skeleton(horse, again_mesh)
    # The placed joints land on the re-export's own joints.
    there = {j.name: np.asarray(j.bind)[:3, 3] for j in curvenet.load_skinned_mesh(again).joints}
    size = np.ptp(np.asarray(again_mesh.vertices), axis=0).max()
    worst = max(np.linalg.norm(np.asarray(j.bind)[:3, 3] - there[j.name]) for j in placed if j.name in there)
    assert worst < 0.01 * size
    unplaced = max(np.linalg.norm(np.asarray(j.bind)[:3, 3] - there[j.name]) for j in bound if j.name in there)
    assert unplaced > 0.1 * size


@needs_data
def test_transfer_to_a_game_lod_lines_up_by_the_skeletons():
    # Blender's decimation of the wolf: Y up, the armature's scale of 100
    wolf = os.path.join(DATA, "quaternius", "Wolf.glb")
    lod = os.path.join(os.path.dirname(__file__), "..", "data", "quaternius", "Wolf_decimated.glb")
    m, low = curvenet.load_mesh(wolf), curvenet.load_mesh(lod)
    s = curvenet.starter(m, wolf)
    t = curvenet.transfer(s.rig, m, low, source_skeleton=wolf, target_skeleton=curvenet.load_skinned_mesh(lod))
    assert t.ok and t.agreement > 0.99
    assert t.report["alignment"].startswith("skeletons: 51 joints matched, scale 100")
    assert t.report["skeleton_fit"]["joints"] == 51
    # without the skeletons, or told to use the frames, the LOD lies far off
    with pytest.raises(curvenet.Error):
        curvenet.transfer(s.rig, m, low)
    with pytest.raises(curvenet.Error):
        curvenet.transfer(s.rig, m, low, align="frames", source_skeleton=wolf, target_skeleton=lod)
    with pytest.raises(curvenet.InputError) as e:
        curvenet.transfer(s.rig, m, low, align="skeletons", target_skeleton=lod)
    assert "has no skeleton" in str(e.value)
    with pytest.raises(curvenet.InputError):
        curvenet.transfer(s.rig, m, low, align="bones")


def test_subdivide_refines_a_cage():
    cube_v = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    quads = np.array([[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])
    s = curvenet.subdivide(curvenet.Mesh(cube_v, quads), 2)
    assert s.num_faces == 6 * 16
    with pytest.raises(curvenet.InputError):
        curvenet.subdivide(curvenet.Mesh(cube_v, quads), 9)


# --- the stub ---------------------------------------------------------------


def test_the_stub_documents_every_public_name():
    stub = os.path.join(os.path.dirname(curvenet.__file__), "__init__.pyi")
    tree = ast.parse(open(stub).read())
    documented = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    public = {n for n in dir(curvenet) if not n.startswith("_")}
    assert public - documented == set()


def test_the_stubs_defaults_are_the_modules():
    # Each keyword's default in the stub, against the one pybind11 gives in
    # the function's signature line (where both are literals).
    stub = os.path.join(os.path.dirname(curvenet.__file__), "__init__.pyi")
    tree = ast.parse(open(stub).read())
    differ = []
    for node in tree.body:
        function = getattr(curvenet, getattr(node, "name", ""), None)
        if not isinstance(node, ast.FunctionDef) or function is None or not function.__doc__:
            continue
        signature = function.__doc__.split("\n")[0]
        a = node.args
        positional = a.posonlyargs + a.args
        defaults = list(zip(positional[len(positional) - len(a.defaults):], a.defaults))
        defaults += [(k, d) for k, d in zip(a.kwonlyargs, a.kw_defaults) if d is not None]
        for arg, default in defaults:
            found = re.search(r"\b" + arg.arg + r": [^=,()]+(?:\[[^\]]*\])? = ([^,)]+)", signature)
            assert found, (node.name, arg.arg, "not in the module's signature")
            try:
                module_value, stub_value = ast.literal_eval(found.group(1)), ast.literal_eval(default)
            except (ValueError, SyntaxError):
                continue  # not a literal on one side (an object's repr)
            if stub_value is Ellipsis:
                continue
            if isinstance(module_value, (list, tuple)) and isinstance(stub_value, (list, tuple)):
                module_value, stub_value = list(module_value), list(stub_value)
            if module_value != stub_value:
                differ.append((node.name, arg.arg, module_value, stub_value))
    assert differ == []


# --- bad values from Python -------------------------------------------------


@needs_data
def test_bad_values_from_python_are_refused_not_crashed_on(tmp_path):
    V, F = tetrahedron()
    with pytest.raises(ValueError):
        curvenet.Mesh(V, F.astype(float))  # indices must be integers, not truncated
    with pytest.raises(curvenet.InputError):
        curvenet.Mesh(np.zeros((0, 3)), np.zeros((0, 3), int))
    m = curvenet.load_mesh(hand())
    rig = curvenet.read_rig(example("hand_l.cnrig.json"))
    nan_node = rig.copy()
    nan_node.nodes[0].position[0] = np.nan
    with pytest.raises(curvenet.InputError) as e:
        curvenet.embed(m, nan_node)
    assert "not finite" in str(e.value) and "nothing was written" not in str(e.value)
    bad_parent = rig.copy()
    bad_parent.joints[3].parent = "Nope"
    with pytest.raises(curvenet.InputError) as e:
        curvenet.bind(m, bad_parent)
    assert e.value.element == "/skeleton/joints/3/parent"
    with pytest.raises(curvenet.InputError):
        curvenet.transfer(rig, m, m, source_frame=np.zeros((4, 4)))
    with pytest.raises(curvenet.InputError):
        curvenet.transfer(rig, m, m, source_frame=np.full((4, 4), np.nan))
    b = curvenet.bind(m, rig)
    with pytest.raises(curvenet.InputError):
        curvenet.skinning_matrices(b, {"Wrist_L": {"translation": [np.nan, 0, 0]}})
    assert b.deform_frames(np.zeros((0, len(b.joints), 4, 4))).shape == (0, b.num_input_vertices, 3)
    with pytest.raises(curvenet.InputError):
        curvenet.write_pc2(str(tmp_path / "nan.pc2"), np.full((1, 2, 3), np.nan))
    assert not (tmp_path / "nan.pc2").exists()
    for start in (float("nan"), float("inf"), 1e300):  # the header's start frame, single precision
        with pytest.raises(curvenet.InputError):
            curvenet.write_pc2(str(tmp_path / "start.pc2"), np.zeros((1, 2, 3)), start)
        assert not (tmp_path / "start.pc2").exists()
    with pytest.raises(curvenet.InputError):
        curvenet.starter(m, [])


# --- baking to a skin ---------------------------------------------------------


@needs_data
def test_baked_weights_and_glb_are_exactly_the_clis(tmp_path):
    glb, csv = tmp_path / "hand.glb", tmp_path / "hand.csv"
    clips_file = hand("hand_l_poses.glb")
    cli("bake", hand(), example("hand_l.cnrig.json"), "-o", str(glb), "--weights-csv", str(csv),
        "--clip", clips_file, "--clip-name", "Grip")
    b = curvenet.bind(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    w = curvenet.bake_weights(b, 4)
    assert w.joint.shape == w.weight.shape == (b.num_input_vertices, 4)
    np.testing.assert_allclose(w.weight.sum(axis=1), 1, atol=1e-12)
    assert (w.weight[w.joint < 0] == 0).all()
    assert curvenet.weights_csv(w) == csv.read_text()
    clips = curvenet.load_skinned_mesh(clips_file)
    assert curvenet.skinned_glb(hand(), b, w, clips, clip_names=["Grip"]) == glb.read_bytes()
    # LBS with the baked weights, at rest, is the rest mesh.
    rest = b.deform(np.stack([np.eye(4)] * len(b.joints)))
    M = curvenet.skinning_matrices(b, example("fist.pose.json"))
    assert np.allclose(curvenet.skin_positions(w, rest, np.stack([np.eye(4)] * len(b.joints))), rest, atol=1e-12)
    # ... and in a pose it lands near the full deformation (the detail term is what it lacks).
    diag = curvenet.load_mesh(hand()).bbox_diagonal()
    gap = np.linalg.norm(curvenet.skin_positions(w, rest, M) - b.deform(M), axis=1)
    assert gap.mean() < 0.02 * diag
    # Weights from arrays, and the npz for painting on top.
    again = curvenet.SkinWeights(w.joints, w.joint, w.weight)
    assert curvenet.weights_csv(again) == csv.read_text()
    curvenet.write_weights_npz(str(tmp_path / "w.npz"), w)
    z = np.load(tmp_path / "w.npz")
    assert (z["joint"] == w.joint).all() and list(z["joints"]) == w.joints
    with pytest.raises(curvenet.InputError):
        curvenet.SkinWeights(w.joints, w.joint + 100, w.weight)
    with pytest.raises(curvenet.InputError):
        curvenet.bake_weights(b, 9)


@needs_data
def test_fitted_weights_over_poses(tmp_path):
    b = curvenet.bind(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    clips = curvenet.load_skinned_mesh(hand("hand_l_poses.glb"))
    poses = np.stack([curvenet.clip_skinning_matrices(b, clips, c, clips.clip_range(c)[1])
                      for c in range(0, clips.num_clips, 2)])
    w = curvenet.fit_weights(b, poses, 4)
    np.testing.assert_allclose(w.weight.sum(axis=1), 1, atol=1e-9)
    assert (w.weight >= 0).all()
    with pytest.raises(ValueError):
        curvenet.fit_weights(b, poses[:, :3], 4)
    # With helper joints: listed after the rig's, and skinned from the rig's matrices alone.
    h = curvenet.fit_weights(b, poses, 4, helpers=5)
    assert 0 < len(h.helpers) <= 5 and h.rig_joints == len(b.joints) == len(h.joints) - len(h.helpers)
    assert all(0 <= a < len(b.joints) and 0 <= c < len(b.joints) and a != c for a, c in h.helpers)
    rest = b.deform(np.stack([np.eye(4)] * len(b.joints)))
    M = poses[1]
    full = np.concatenate([M, [curvenet.helper_matrix(M[a], M[c]) for a, c in h.helpers]])
    np.testing.assert_allclose(curvenet.skin_positions(h, rest, M), curvenet.skin_positions(h, rest, full), atol=0)
    again = curvenet.SkinWeights(h.joints, h.joint, h.weight, h.helpers)
    assert again.helpers == h.helpers and curvenet.weights_csv(again) == curvenet.weights_csv(h)
    curvenet.write_weights_npz(str(tmp_path / "h.npz"), h)
    z = np.load(tmp_path / "h.npz")
    back = curvenet.SkinWeights(list(z["joints"]), z["joint"], z["weight"], [tuple(p) for p in z["helpers"]])
    assert back.helpers == h.helpers and curvenet.weights_csv(back) == curvenet.weights_csv(h)
    with pytest.raises(curvenet.InputError):
        curvenet.SkinWeights(h.joints, h.joint, h.weight, [(0, len(h.joints))])


@needs_data
def test_weights_fitted_over_the_skeletons_own_poses_are_exactly_the_clis(tmp_path):
    # `curvenet bake --weights fitted` fits over training_poses: the same poses
    # from Python give the same weights, to the digit.
    csv = tmp_path / "fitted.csv"
    cli("bake", hand(), example("hand_l.cnrig.json"), "-o", str(tmp_path / "fitted.glb"), "--weights", "fitted",
        "--weights-csv", str(csv))
    b = curvenet.bind(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    poses = curvenet.training_poses(b)
    J = len(b.joints)
    assert poses.shape == (J * (2 * 2 * 2 + 2) + 48, J, 4, 4)
    R = poses[..., :3, :3]
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    assert curvenet.weights_csv(curvenet.fit_weights(b, poses, 4)) == csv.read_text()
    # The options shape the poses: no bends and no random poses leave the two twists of each joint.
    assert curvenet.training_poses(b, bends=[], random_poses=0).shape == (2 * J, J, 4, 4)
    with pytest.raises(ValueError):
        curvenet.training_poses(b, random_poses=-1)


@needs_data
def test_the_gradient_mode_gives_exactly_the_clis_output(tmp_path):
    out = tmp_path / "fist_gradient.obj"
    cli("pose", example("hand_l_welded.obj"), example("hand_l.cnrig.json"), example("fist.pose.json"),
        "-o", str(out), "--method", "gradient")
    b = curvenet.bind(curvenet.load_mesh(example("hand_l_welded.obj")), curvenet.read_rig(example("hand_l.cnrig.json")),
                      method="gradient")
    assert b.method == "gradient"
    P = b.deform(curvenet.skinning_matrices(b, example("fist.pose.json")))
    assert np.array_equal(P, read_obj_vertices(out))
    with pytest.raises(ValueError):
        curvenet.bind(curvenet.load_mesh(example("hand_l_welded.obj")), curvenet.read_rig(example("hand_l.cnrig.json")),
                      method="spline")


@needs_data
def test_a_farm_job_from_python_merges_to_the_cli_animation(tmp_path):
    mesh = clips = os.path.join(DATA, "cesium_man", "CesiumMan.glb")  # a walk: every frame differs
    rig = str(tmp_path / "cesium.cnrig.json")
    cli("starter", mesh, "-o", rig)
    single = tmp_path / "single.pc2"
    cli("animate", mesh, rig, clips, "--fps", "100", "--frames", "0:44", "-o", str(single))
    folder = curvenet.farm_submit(mesh, rig, clips, str(tmp_path / "job"), output=str(tmp_path / "merged.pc2"),
                                  fps=100.0, frames="0:44", shard_frames=10, executable=CLI, dry_run=True)
    assert folder == str((tmp_path / "job").resolve())
    assert [s["state"] for s in curvenet.farm_status(folder)] == ["missing"] * 5
    for i in range(5):  # what each Slurm array task runs
        cli("farm", "task", folder, str(i))
    status = curvenet.farm_status(folder)
    assert [(s["first"], s["last"], s["state"]) for s in status] == [(f, f + 9 if f < 40 else 44, "done")
                                                                      for f in range(0, 45, 10)]
    r = curvenet.farm_merge(folder)
    assert r == {"output": str((tmp_path / "merged.pc2").resolve()), "frames": 45, "vertices": 3273, "parts": 5}
    assert (tmp_path / "merged.pc2").read_bytes() == single.read_bytes()
    os.remove(os.path.join(folder, "parts", "part_0003.frames"))
    with pytest.raises(curvenet.InputError, match=r"part_0003.frames: missing.*--array=3 "):
        curvenet.farm_merge(folder)


@needs_data
def test_animate_poses_streams_what_deform_frames_gives(tmp_path):
    b = curvenet.bind(curvenet.load_mesh(hand()), curvenet.read_rig(example("hand_l.cnrig.json")))
    clips = curvenet.load_skinned_mesh(hand("hand_l_poses.glb"))
    clip = clips.find_clip("Grip")
    asked = []

    def pose(f):
        asked.append(f)
        return curvenet.clip_skinning_matrices(b, clips, clip, f / 24.0)

    curvenet.animate_poses(b, pose, 3, 40, str(tmp_path / "poses.pc2"))
    assert asked == list(range(3, 41))  # each frame once, in order
    M = np.stack([pose(f) for f in range(3, 41)])
    curvenet.write_pc2(str(tmp_path / "frames.pc2"), b.deform_frames(M), 3.0)
    assert (tmp_path / "poses.pc2").read_bytes() == (tmp_path / "frames.pc2").read_bytes()
    with pytest.raises(ValueError, match=r"pose\(3\): expected a"):
        curvenet.animate_poses(b, lambda f: np.eye(4), 3, 5, str(tmp_path / "bad.pc2"))
    with pytest.raises(ZeroDivisionError):
        curvenet.animate_poses(b, lambda f: 1 / 0, 3, 5, str(tmp_path / "bad.pc2"))
    assert not (tmp_path / "bad.pc2").exists()


@needs_data
def test_a_layer_over_the_skin_gives_what_the_cli_gives_and_a_pulled_node_moves_its_region(tmp_path):
    mesh_file, rig_file = hand(), example("hand_l.cnrig.json")
    pull = os.path.join(os.path.dirname(__file__), "..", "data", "hand", "fist_pull.pose.json")
    mesh, rig = curvenet.load_mesh(mesh_file), curvenet.read_rig(rig_file)
    skin = curvenet.load_skinned_mesh(mesh_file)
    layer = curvenet.bind_layer(mesh, rig, skin=skin)
    assert layer.over_skin
    M = curvenet.skinning_matrices(layer.joints, pull)
    offsets = curvenet.read_pose_nodes(pull)
    assert set(offsets) == {"index_pip_1", "index_pip_2"}
    for envelope in (0.0, 1.0):
        out = tmp_path / ("layer_%g.obj" % envelope)
        cli("pose", mesh_file, rig_file, pull, "-o", str(out), "--over-skin", "--envelope", str(envelope))
        mine = layer.deform(M, envelope=envelope, offsets=offsets)
        assert np.array_equal(read_obj_vertices(out), mine)  # 17 digits: the same doubles
    base = layer.deform(M, envelope=0.0)
    plain = layer.deform(M)
    pulled = layer.deform(M, offsets=offsets)
    moved = np.linalg.norm(pulled - plain, axis=1)
    diag = mesh.bbox_diagonal()
    assert 0.01 * diag < moved.max() < 0.03 * diag  # about the 4 mm (2 %) pull
    assert np.linalg.norm(plain - base, axis=1).max() > 1e-3 * diag  # the layer corrects the skin
    with pytest.raises(ValueError, match="envelope"):
        layer.deform(M, envelope=1.5)
    # Over the net's own deformation: no offsets, no change.
    over_net = curvenet.bind_layer(mesh, rig)
    b = curvenet.bind(mesh, rig)
    assert np.array_equal(over_net.deform(M), b.deform(M))


@needs_data
def test_a_layer_takes_another_mask_without_binding_again_and_bakes_its_keyed_envelope_and_offsets(tmp_path):
    mesh_file, rig_file = hand(), example("hand_l.cnrig.json")
    pull = os.path.join(os.path.dirname(__file__), "..", "data", "hand", "fist_pull.pose.json")
    mesh, rig = curvenet.load_mesh(mesh_file), curvenet.read_rig(rig_file)
    layer = curvenet.bind_layer(mesh, rig, skin=curvenet.load_skinned_mesh(mesh_file))
    M = curvenet.skinning_matrices(layer.joints, pull)
    offsets = curvenet.read_pose_nodes(pull)
    n = layer.num_input_vertices
    assert layer.mask.size == 0
    # a mask of 0 on the first half: that half is the skin exactly, the rest the whole layer
    mask = np.ones(n)
    mask[: n // 2] = 0
    masked = layer.with_mask(mask)
    assert np.array_equal(masked.mask, mask) and layer.mask.size == 0  # the original keeps its own
    base, full, part = layer.deform(M, envelope=0.0), layer.deform(M), masked.deform(M)
    assert np.array_equal(part[: n // 2], base[: n // 2])
    assert np.array_equal(part[n // 2 :], full[n // 2 :])
    assert np.abs(full - base).max() > 0  # the mask hides something
    assert np.array_equal(masked.with_mask(None).deform(M), full)
    with pytest.raises(curvenet.InputError, match="vertex 3"):
        layer.with_mask(np.where(np.arange(n) == 3, 2.0, 1.0))
    with pytest.raises(curvenet.InputError):
        layer.with_mask(np.ones(n - 1))
    # a mask by region, by the keys of the embedding's report: one region held at the skin
    keys = [r["key"] for r in layer.binding.embedding.report["region_list"]]
    by_region = layer.region_mask({keys[0]: 0.0})
    assert by_region.shape == (n,) and 0 < np.count_nonzero(by_region == 0) < n
    held = layer.with_mask(by_region).deform(M)
    assert np.array_equal(held[by_region == 0], base[by_region == 0])
    assert np.array_equal(held[by_region == 1], full[by_region == 1])
    assert np.array_equal(layer.region_mask({}, others=0.0), np.zeros(n))
    # with a falloff, the held region's value rises towards its curves, and only there
    soft = layer.region_mask({keys[0]: 0.0}, falloff=0.05)
    assert np.all(soft >= by_region) and np.all(soft[by_region == 1] == 1)
    assert 0 < np.count_nonzero((soft > 0) & (soft < 1))
    with pytest.raises(curvenet.InputError, match="falloff"):
        layer.region_mask({keys[0]: 0.0}, falloff=2.0)
    with pytest.raises(curvenet.InputError, match="no region of the net has this key"):
        layer.region_mask({"nope:L": 0.0})

    # the frame job through a layer: each frame's envelope and offsets, as deform gives them
    def pose(f):
        return (M, (f - 1) / 4, offsets if f % 2 else None)

    path = tmp_path / "layer.pc2"
    curvenet.animate_poses(masked, pose, 1, 5, str(path))
    frames, start = read_pc2(path)
    assert frames.shape == (5, n, 3) and start == 1
    for k, f in enumerate(range(1, 6)):
        _, envelope, o = pose(f)
        want = masked.deform(M, envelope=envelope, offsets=o).astype(np.float32)
        assert np.array_equal(frames[k], want)
    # plain matrices are envelope 1 without offsets
    curvenet.animate_poses(layer, lambda f: M, 1, 2, str(path))
    assert np.array_equal(read_pc2(path)[0][1], full.astype(np.float32))
    with pytest.raises(curvenet.InputError, match="envelope"):
        curvenet.animate_poses(layer, lambda f: (M, 2.0, None), 1, 2, str(tmp_path / "bad.pc2"))
    assert not (tmp_path / "bad.pc2").exists()
    with pytest.raises(TypeError):
        curvenet.animate_poses(mesh, lambda f: M, 1, 2, str(tmp_path / "bad.pc2"))


# --- the net editor ---------------------------------------------------------


@needs_data
def test_the_net_editor_edits_a_copy_that_still_embeds():
    mesh = curvenet.load_mesh(hand())
    rig = curvenet.read_rig(example("hand_l.cnrig.json"))
    regions = curvenet.embed(mesh, rig).report["regions"]
    p = rig.profiles[0]
    split, node, new_profile = curvenet.split_profile(rig, p.id, 0.5)
    assert len(rig.nodes) + 1 == len(split.nodes)  # the input is a copy, unchanged
    assert split.profile(p.id).to == node and split.profile(new_profile).from_ == node
    rep = curvenet.embed(mesh, split).report
    assert rep["ok"] and rep["regions"] == regions  # one node and one profile more: the same regions
    t = curvenet.nearest_parameter(rig, p.id, split.node(node).position)
    assert abs(t - 0.5) < 1e-9
    with pytest.raises(curvenet.InputError):
        curvenet.nearest_parameter(rig, p.id, [np.nan, 0, 0])
    merged = curvenet.merge_nodes(split, p.from_, node)
    assert len(merged.nodes) == len(rig.nodes) and merged.node_index(node) < 0
    moved = curvenet.move_node(rig, p.from_, np.asarray(rig.node(p.from_).position) + 1e-4)
    assert np.allclose(moved.profile(p.id).curve.points[0], np.asarray(rig.node(p.from_).position) + 1e-4)
    fewer = curvenet.remove_profiles(rig, [p.id])
    assert len(fewer.profiles) == len(rig.profiles) - 1
    with pytest.raises(curvenet.InputError) as e:
        curvenet.remove_nodes(rig, ["no such node"], "fox")
    assert e.value.file == "fox" and e.value.element == "no such node"
    with pytest.raises(curvenet.InputError):
        curvenet.split_profile(rig, p.id, 1.0)
    weighted = curvenet.set_joint_weight(rig, [p.from_], rig.joints[0].name, 0.25)
    w = dict(weighted.weights[p.from_])
    assert abs(w[rig.joints[0].name] - 0.25) < 1e-12 and abs(sum(w.values()) - 1) < 1e-12
    rerouted = curvenet.reroute_profile(rig, p.id, np.asarray(p.curve.points)[1:-1])
    assert len(rerouted.profile(p.id).curve.points) == len(p.curve.points)
