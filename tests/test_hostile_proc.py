"""Faults that need real processes or real runs: broken pipes, Ctrl-C/SIGTERM, SIGKILL of a sweep driver,
divergence, and run folders that tell the truth (running / complete / interrupted / diverged)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from continuum_sim.cli import EXIT_BROKEN_PIPE, EXIT_DIVERGED, EXIT_INTERRUPTED, EXIT_TERMINATED, EXIT_USAGE, main
from continuum_sim.configio import ConfigError
from continuum_sim.runfolder import MARKER, finish, mark_running, prepare_run_folder, read_state

CLI = [sys.executable, "-m", "continuum_sim"]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1]) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _as_from_a_terminal() -> None:
    """Child setup: SIGINT at its default, as in a terminal. A shell runs background jobs
    (``cmd &``) with SIGINT ignored and children inherit that, so a test suite started that
    way would otherwise test a process that is told to ignore Ctrl-C."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_broken_pipe_is_silent():
    # `continuum-sim fk ... | head -c0`: the reader is gone before the first write.
    proc = subprocess.Popen([*CLI, "fk", "0.5", "0", "0.3", "0", "0", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=_env())
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == EXIT_BROKEN_PIPE, err
    assert b"Traceback" not in err and b"BrokenPipe" not in err


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    end = time.monotonic() + timeout
    while not path.exists():
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < end, f"{path} never appeared"
        time.sleep(0.05)


@pytest.mark.parametrize("sig, code, video", [(signal.SIGINT, EXIT_INTERRUPTED, True), (signal.SIGTERM, EXIT_TERMINATED, False)],
                         ids=["ctrl-c-video", "sigterm"])
def test_interrupted_run_is_one_line_and_marked(tmp_path, sig, code, video):
    out = tmp_path / "run"
    argv = [*CLI, "run", "--quiet", "--out", str(out), *(["--video"] if video else [])]
    # A process group of its own: Ctrl-C in a terminal reaches every process of the group (render workers too).
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), process_group=0,
                            preexec_fn=_as_from_a_terminal)
    _wait_for(out / "config.toml", proc)  # past planning: the model is built and the run folder is being filled
    assert read_state(out) == "running"
    time.sleep(2.0)  # video: the render workers are up
    if sig == signal.SIGINT:
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "interrupted" in _one_line(err) or "terminated" in _one_line(err)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "interrupted" and metrics["status_reason"]
    assert not (out / MARKER).exists() and not (out / "video.mp4").exists()
    assert read_state(out) == "interrupted"


def test_diverged_run_is_marked(tmp_path, capsys):
    config = tmp_path / "diverge.toml"
    # An explicit stiff cable spring at a 10 ms step: unstable (docs/plant.md, "Tension chatter").
    config.write_text("[model]\ntimestep = 0.01\ncable_implicit_spring = false\nstable_step = false\ncable_max_force = 1.0e5\n")
    out = tmp_path / "run"
    assert main(["run", "--quiet", "--config", str(config), "--out", str(out)]) == EXIT_DIVERGED
    assert "diverged" in _one_line(capsys.readouterr().err)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "diverged" and "diverged" in metrics["status_reason"]
    assert not (out / MARKER).exists() and read_state(out) == "diverged"
    # The folder now holds a run: a second run into it is refused, nothing is touched.
    before = sorted(p.name for p in out.iterdir())
    assert main(["run", "--quiet", "--out", str(out)]) == EXIT_USAGE
    assert "already holds a run (diverged)" in _one_line(capsys.readouterr().err)
    assert sorted(p.name for p in out.iterdir()) == before


def test_overwrite_clears_only_run_folders(tmp_path):
    run = tmp_path / "run"
    mark_running(run)
    (run / "config.toml").write_text("old\n")
    (run / "video.mp4").write_bytes(b"old video")
    (run / "plots").mkdir()
    (run / "plots" / "a.png").write_bytes(b"png")
    finish(run, "complete")
    assert read_state(run) == "complete"
    with pytest.raises(ConfigError, match="already holds a run \\(complete\\); pass --overwrite"):
        prepare_run_folder(run, overwrite=False)
    prepare_run_folder(run, overwrite=True)
    assert list(run.iterdir()) == []
    home = tmp_path / "home"
    home.mkdir()
    (home / "thesis.tex").write_text("precious\n")
    with pytest.raises(ConfigError, match="not a run folder"):
        prepare_run_folder(home, overwrite=True)
    assert (home / "thesis.tex").exists()


def test_killed_run_reads_incomplete_and_in_use_folder_is_not_cleared(tmp_path):
    run = tmp_path / "run"
    mark_running(run)  # this process: alive
    marker = json.loads((run / MARKER).read_text())
    assert marker["status"] == "running" and marker["pid"] == os.getpid()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (run / MARKER).write_text(json.dumps({"status": "running", "pid": int(dead.stdout)}))
    assert read_state(run) == "incomplete"  # SIGKILLed: marker left, process gone
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (run / MARKER).write_text(json.dumps({"status": "running", "pid": child.pid}))
        assert read_state(run) == "running"
        with pytest.raises(ConfigError, match="in use by a running run"):
            prepare_run_folder(run, overwrite=True)
    finally:
        child.kill()
        child.wait()


def test_interrupted_video_is_not_left_under_the_final_name(tmp_path):
    run = tmp_path / "run"
    mark_running(run)
    (run / "video.mp4").write_bytes(b"19.5 of 51.3 s")
    finish(run, "interrupted", "KeyboardInterrupt")
    assert not (run / "video.mp4").exists() and (run / "video.interrupted.mp4").exists()
    assert json.loads((run / "metrics.json").read_text())["status"] == "interrupted"


def _children(pid: int) -> set[int]:
    """All descendants of ``pid`` (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    out, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, parent in parents.items() if parent in frontier} - out
        out |= frontier
    return out


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.parametrize("how", ["sigkill", "ctrl-c"])
def test_stopped_sweep_driver_leaves_no_workers(tmp_path, how):
    spec = tmp_path / "slow.toml"
    spec.write_text('[grid]\n"model.stiffness_scale" = [1.0, 1.1, 1.2, 1.3]\n[evaluation]\nkind = "gravity_sag"\nsettle_s = 100.0\n')
    driver = subprocess.Popen([*CLI, "sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "2", "--batch", "off",
                               "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=_env(),
                              process_group=0, preexec_fn=_as_from_a_terminal)
    end = time.monotonic() + 120
    workers: set[int] = set()
    while len(workers) < 4 and time.monotonic() < end:  # resource tracker, forkserver, two workers
        assert driver.poll() is None
        time.sleep(0.2)
        workers = _children(driver.pid)
    assert len(workers) >= 4
    if how == "sigkill":  # the forkserver and the two workers go at once (kernel signal, pidfd watchers): within 1 s
        pool = {p for p in workers if b"resource_tracker" not in _cmdline(p)}
        driver.kill()
        driver.wait()
        end = time.monotonic() + 1.0
        while any(_alive(p) for p in pool) and time.monotonic() < end:
            time.sleep(0.02)
        assert not [p for p in pool if _alive(p)], "pool processes alive 1 s after the driver's SIGKILL"
    else:
        time.sleep(1.0)  # the workers are inside their variants
        os.killpg(driver.pid, signal.SIGINT)
        _, err = driver.communicate(timeout=60)
        assert driver.returncode == EXIT_INTERRUPTED
        assert "rerun to resume" in _one_line(err)
    end = time.monotonic() + 30
    while any(_alive(p) for p in workers) and time.monotonic() < end:
        time.sleep(0.2)
    left = [p for p in workers if _alive(p)]
    for pid in left:  # do not leave them behind even when the test fails
        os.kill(pid, signal.SIGKILL)
    assert not left, f"orphan processes {left}"


def test_sigkill_of_a_video_run_leaves_no_render_workers(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([*CLI, "run", "--quiet", "--video", "--out", str(out)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=_env(), process_group=0)
    end = time.monotonic() + 120
    helpers: set[int] = set()
    while len(helpers) < 2 and time.monotonic() < end:  # resource tracker + at least one render worker
        assert proc.poll() is None
        time.sleep(0.2)
        helpers = _children(proc.pid)
    assert len(helpers) >= 2
    time.sleep(1.0)
    proc.kill()
    proc.wait()
    end = time.monotonic() + 30
    while any(_alive(p) for p in helpers) and time.monotonic() < end:
        time.sleep(0.2)
    left = [p for p in helpers if _alive(p)]
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert not left, f"orphan processes {left}"
    assert read_state(out) == "incomplete" and not (out / "video.mp4").exists()


def test_full_disk_keeps_the_metrics(tmp_path):
    """write_run writes the 3 kB metrics.json before the MB-sized trajectory: a full disk loses only the latter."""
    import errno

    from continuum_sim.scenario.runner import write_run

    class FullDisk:
        def save(self, path):
            raise OSError(errno.ENOSPC, "No space left on device", str(path))

    with pytest.raises(OSError, match="No space left"):
        write_run(tmp_path, FullDisk(), {"sample_detached": True}, plan=None, config=None)
    assert json.loads((tmp_path / "metrics.json").read_text()) == {"sample_detached": True}
    assert not (tmp_path / "trajectory.npz").exists()


@pytest.fixture(scope="module")
def short_runs(tmp_path_factory):
    """The same short run (first stage only, ~3 s) twice, into two folders."""
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import run_scenario

    root = tmp_path_factory.mktemp("twice")
    for name in ("a", "b"):
        run_scenario(ScenarioConfig.default(), root / name, stages=("initial",), progress=False)
    return root / "a", root / "b"


def test_identical_runs_write_identical_trajectories(short_runs):
    a, b = short_runs
    assert (a / "trajectory.npz").read_bytes() == (b / "trajectory.npz").read_bytes()
    metrics = json.loads((a / "metrics.json").read_text())
    assert metrics["wall_seconds"] > 0 and metrics["wall_breakdown_s"]  # wall figures live here, only here
    assert main(["metrics", str(a)]) == 0  # recomputed from the folder: the same text (wall keys carried over)


GL_HARNESS = """
import json, sys
from continuum_sim import glbackend
from continuum_sim.cli import main
codes = {}
for name, argv in json.loads(sys.argv[1]):
    codes[name] = main(argv)
    codes[name + " loaded GL"] = sorted(m for m in sys.modules if m.split(".")[0] == "OpenGL" or m.startswith("mujoco.osmesa")
                                        or m.startswith("mujoco.egl") or m.startswith("dm_control._render.pyopengl"))
glbackend.library_found = lambda backend: backend == "egl"  # no OSMesa on any machine, for the command that renders
codes["run --video"] = main(["run", "--video", "--quiet", "--out", sys.argv[2]])
print(json.dumps(codes))
"""


def test_commands_that_render_nothing_never_load_gl(short_runs, tmp_path):
    """MUJOCO_GL=osmesa without OSMesa: build-model exited 70 (dm_control loaded the backend); now no GL is loaded
    by build-model, plan, fk or metrics, and run --video is refused in one line, before any work."""
    commands = [("build-model", ["build-model", "--models-only", "--out", str(tmp_path / "models")]),
                ("plan", ["plan", "--no-plots", "--out", str(tmp_path / "plan")]),
                ("fk", ["fk", "0.3", "0", "0.2", "1", "0.1", "2"]),
                ("metrics", ["metrics", str(short_runs[0])])]
    env = {**_env(), "MUJOCO_GL": "osmesa"}
    env.pop("PYOPENGL_PLATFORM", None)
    proc = subprocess.run([sys.executable, "-c", GL_HARNESS, json.dumps(commands), str(tmp_path / "video")],
                          capture_output=True, text=True, env=env, timeout=300)
    codes = json.loads(proc.stdout.splitlines()[-1])
    for name, _ in commands:
        assert codes[name] == 0 and codes[name + " loaded GL"] == [], (name, codes, proc.stderr)
    assert codes["run --video"] == EXIT_USAGE
    line = _one_line(proc.stderr)
    assert "MUJOCO_GL=osmesa: OSMesa not found (apt-get install libosmesa6)" in line and "MUJOCO_GL=egl" in line
    assert not (tmp_path / "video").exists()
