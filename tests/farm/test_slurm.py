"""`curvenet farm` on a real one-node Slurm cluster started for the test.

The cluster (tests/farm/slurm_cluster.sh) runs munged, slurmctld and slurmd
in a temporary folder on private ports, and is stopped by PID at the end.
If it cannot start, the test fails and says why: it does not skip. Without
the shared data (CesiumMan) the module is skipped.

Environment: CURVENET_CLI (the curvenet program), CURVENET_DATA_DIR.
"""

import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
CLI = os.environ.get("CURVENET_CLI", "curvenet")
DATA = Path(os.environ.get("CURVENET_DATA_DIR", HERE.parents[2] / "shared" / "data"))
# CesiumMan's walk (2 s), sampled finely so that every frame differs: the
# hand's 35 clips are one pose each.
MESH = CLIPS = DATA / "cesium_man" / "CesiumMan.glb"
FPS = ("--fps", "200")
TIMEOUT = 180  # seconds for a job to finish on a busy 2-core machine

# Every test is skipped, not the module: pytest exits non-zero when it collects nothing.
pytestmark = pytest.mark.skipif(not MESH.is_file(), reason=f"no shared data ({MESH} is missing)")


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    path = tmp_path_factory.mktemp("rig") / "cesium.cnrig.json"
    r = subprocess.run([CLI, "starter", str(MESH), "-o", str(path)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return path


@pytest.fixture(scope="module")
def slurm():
    folder = Path(tempfile.mkdtemp(prefix="curvenet-slurm-"))
    script = HERE / "slurm_cluster.sh"
    env = dict(os.environ)
    for k in list(env):  # a test run inside a Slurm job must not talk to that cluster
        if k.startswith(("SLURM_", "SBATCH_", "SQUEUE_")):
            del env[k]
    started = subprocess.run([str(script), "start", str(folder)], env=env, capture_output=True, text=True)
    if started.returncode != 0:
        subprocess.run([str(script), "stop", str(folder)], env=env, capture_output=True)
        pytest.fail("the one-node Slurm cluster did not start:\n" + started.stderr[-4000:], pytrace=False)
    env["SLURM_CONF"] = str(folder / "slurm.conf")
    env["PATH"] = str(Path(CLI).resolve().parent) + os.pathsep + env.get("PATH", "")
    try:
        yield env
    finally:
        stopped = subprocess.run([str(script), "stop", str(folder)], env=env, capture_output=True, text=True)
        assert stopped.returncode == 0, stopped.stderr
        for name in ("munged", "slurmctld", "slurmd"):
            pid_file = folder / f"{name}.pid.launch"
            assert not pid_file.exists(), f"{name} was not stopped"


def run(env, *args, check=True):
    r = subprocess.run([CLI, *map(str, args)], env=env, capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"curvenet {' '.join(map(str, args))} exited {r.returncode}:\n{r.stdout}{r.stderr}")
    return r


def states(env, folder):
    r = run(env, "farm", "status", folder, check=False)
    out = {}
    for line in r.stdout.splitlines():
        if line.startswith("task "):
            index = int(line.split()[1])
            out[index] = line.split(": ", 1)[1].split(" ")[0]
    return out, r


def wait_until_settled(env, folder, count):
    """Until no task is pending or running; returns the states."""
    deadline = time.time() + TIMEOUT
    while time.time() < deadline:
        s, r = states(env, folder)
        assert "squeue" in r.stdout.splitlines()[0], r.stdout  # the queue was asked
        if len(s) == count and all(v not in ("PENDING", "RUNNING", "CONFIGURING", "COMPLETING") for v in s.values()):
            return s
        time.sleep(0.5)
    raise AssertionError(f"the farm job in {folder} did not finish in {TIMEOUT} s:\n{states(env, folder)[1].stdout}")


def sbatch(env, line):
    """Runs an sbatch line as curvenet printed it; returns the job id."""
    r = subprocess.run(shlex.split(line), env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().split(";")[0]


def rerun_line(message):
    assert "rerun only" in message, message
    return message.split(" with: ", 1)[1].strip()


def animate(env, rig, tmp, out_name, *extra):
    out = tmp / out_name
    run(env, "animate", MESH, rig, CLIPS, "-o", out, *extra)
    return out.read_bytes()


def test_eight_shards_merge_bit_for_bit_and_a_truncated_part_is_rerun_alone(slurm, rig, tmp_path):
    env = slurm
    single = animate(env, rig, tmp_path, "single.pc2", "--frames", "8:399", *FPS)
    job = tmp_path / "job"
    r = run(env, "farm", "submit", MESH, rig, CLIPS, "--frames", "8:399", *FPS, "--shard-frames", "49",
            "--folder", job, "-o", tmp_path / "merged.pc2")
    assert "tasks: 8 of at most 49 frames" in r.stdout, r.stdout
    assert "slurm job: " in r.stdout
    s = wait_until_settled(env, job, 8)
    assert all(v == "done" for v in s.values()), s
    logs = "".join(p.read_text() for p in (job / "logs").glob("task_*.log"))
    assert logs.count("building the binding cache") == 1, logs  # bound once, read by the others
    run(env, "farm", "merge", job)
    assert (tmp_path / "merged.pc2").read_bytes() == single
    frame = 12 * 3273  # bytes of one frame: the walk moves, so no two shards could be swapped unseen
    frames = [single[32 + k * frame: 32 + (k + 1) * frame] for k in (0, 49, 98, 391)]
    assert len(set(frames)) == 4

    # A part truncated by hand: named, with the sbatch line for it alone.
    part = job / "parts" / "part_0005.frames"
    data = part.read_bytes()
    part.write_bytes(data[: len(data) // 3])
    (tmp_path / "merged.pc2").unlink()
    bad = run(env, "farm", "merge", job, check=False)
    assert bad.returncode == 2 and "part_0005.frames" in bad.stderr and "truncated" in bad.stderr, bad.stderr
    assert not (tmp_path / "merged.pc2").exists()
    line = rerun_line(bad.stderr)
    assert "--array=5 " in line, line
    sbatch(env, line)
    time.sleep(1)
    s = wait_until_settled(env, job, 8)
    assert all(v == "done" for v in s.values()), s
    run(env, "farm", "merge", job)
    assert (tmp_path / "merged.pc2").read_bytes() == single


def test_a_task_cancelled_mid_frame_leaves_no_part_and_is_rerun_alone(slurm, rig, tmp_path):
    env = slurm
    # Two long shards in the gradient mode, so that one can be cancelled
    # while it writes its frames (CesiumMan's 2 s walk at 1500 fps).
    extra = ("--frames", "60:3059", "--fps", "1500", "--method", "gradient")
    job = tmp_path / "job"
    run(env, "farm", "submit", MESH, rig, CLIPS, "--shard-frames", "1500", "--folder", job, "-o",
        tmp_path / "merged.pc2", *extra)
    job_id = (job / "slurm_job_ids").read_text().split()[0]
    parts = job / "parts"
    deadline = time.time() + TIMEOUT
    cancelled = False
    while time.time() < deadline and not cancelled:
        for tmp in parts.glob("part_0001.frames.tmp-curvenet-*"):
            if tmp.stat().st_size > 1 << 20:  # a megabyte of frames written, and more to come
                subprocess.run(["scancel", f"{job_id}_1"], env=env, check=True)
                cancelled = True
        time.sleep(0.02)
    assert cancelled, "task 1 was never seen writing its frames"
    s = wait_until_settled(env, job, 2)
    assert s[0] == "done" and s[1] != "done", s
    assert not (parts / "part_0001.frames").exists()
    bad = run(env, "farm", "merge", job, check=False)
    assert bad.returncode == 2 and "part_0001.frames: missing" in bad.stderr, bad.stderr
    sbatch(env, rerun_line(bad.stderr))
    time.sleep(1)
    s = wait_until_settled(env, job, 2)
    assert s == {0: "done", 1: "done"}, s
    assert not list(parts.glob("*.tmp-curvenet-*")), "the killed task's temporary file was left"
    run(env, "farm", "merge", job)
    assert (tmp_path / "merged.pc2").read_bytes() == animate(env, rig, tmp_path, "single.pc2", *extra)


def test_a_binding_cache_lock_held_by_a_dead_task_is_taken_over(slurm, rig, tmp_path):
    env = slurm
    job = tmp_path / "job"
    r = run(env, "farm", "submit", MESH, rig, CLIPS, "--frames", "0:59", "--shard-frames", "20", "--folder", job,
            "--obj-sequence", tmp_path / "frames", "--dry-run")
    line = r.stdout.split("submit with: ", 1)[1].strip()
    assert not (job / "slurm_job_ids").exists()  # a dry run submits nothing
    # A task that took the lock and died: the PID of a process that exited.
    dead = subprocess.Popen(["true"])
    dead.wait()
    host = os.uname().nodename
    (job / "binding.cache.lock").write_text(f"{host} {dead.pid}\n")
    sbatch(env, line)
    s = wait_until_settled(env, job, 3)
    assert all(v == "done" for v in s.values()), s
    logs = "".join(p.read_text() for p in (job / "logs").glob("task_*.log"))
    assert "which is gone: binding here" in logs, logs
    assert not (job / "binding.cache.lock").exists()
    run(env, "farm", "merge", job)
    run(env, "animate", MESH, rig, CLIPS, "--frames", "0:59", "--obj-sequence", tmp_path / "single")
    names = sorted(p.name for p in (tmp_path / "single").glob("*.obj"))
    assert len(names) == 60
    for n in names:
        assert (tmp_path / "frames" / n).read_bytes() == (tmp_path / "single" / n).read_bytes(), n


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
