"""A real two-node Ray cluster with token authentication, on loopback: studies through ``--address`` match the local run.

The cluster (a head and a second node, one CPU each) runs in a helper process started by
this module, every address 127.0.0.1 (its servers listen there only), with
``RAY_AUTH_MODE=token`` and a token generated here. Each study connects once, gets the
token through the environment only (``RAY_AUTH_TOKEN``, no ``RAY_AUTH_MODE``: the driver
turns token mode on itself), and records the same results as the local backend; a wrong
or missing token, or another Ray version, is one line naming the cause, exit 2. The helper's nodes are stopped
in a finally, and no process of this cluster may survive.
"""

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("ray")
psutil = pytest.importorskip("psutil")  # a dependency of ray

ROOT = Path(__file__).resolve().parents[1]

# Two nodes as Ray's own multi-node tests start them (ray.cluster_utils.Cluster does the same, but also writes the
# address into Ray's default temp folder, which a `ray.init()` elsewhere on this machine would then pick up). The
# `ray start` command cannot do this on loopback: it replaces 127.0.0.1 with the machine's outward address.
NODES = """\
import sys
from ray._private.node import Node
from ray._private.parameter import RayParams

port, temp_dir = int(sys.argv[1]), sys.argv[2]
common = dict(node_ip_address="127.0.0.1", num_cpus=1, num_gpus=0, temp_dir=temp_dir, include_dashboard=False,
              object_store_memory=80 * 1024 * 1024, min_worker_port=0, max_worker_port=0)
nodes = []
try:
    head = Node(RayParams(**common, gcs_server_port=port), head=True, shutdown_at_exit=True, spawn_reaper=True)
    nodes.append(head)
    nodes.append(Node(RayParams(**common, gcs_address=head.gcs_address, include_log_monitor=False, node_manager_port=0,
                                dashboard_agent_listen_port=None), head=False, shutdown_at_exit=True, spawn_reaper=True))
    print("READY", head.gcs_address, flush=True)
    sys.stdin.read()  # until the test closes it
finally:
    for node in reversed(nodes):
        node.kill_all_processes(check_alive=False, allow_graceful=True)
"""

# Ray maps a loopback address to the machine's outward one unless told this is no multi-node setup; the driver then
# connects to 127.0.0.1 and finds its node there.
LOOPBACK = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}

SWEEP = """\
metrics = ["sag_mm", "pcc_error_mm"]
[grid]
"model.stiffness_scale" = [0.5, 1.0, 300.0]
[evaluation]
kind = "gravity_sag"
settle_s = 0.2
"""

SENSITIVITY = """\
method = "morris"
parameters = ["model.joint_damping"]
metrics = ["sag_mm"]
[morris]
trajectories = 2
[evaluation]
kind = "gravity_sag"
settle_s = 0.2
"""

OPTIMIZE = """\
[variables]
"model.stiffness_scale" = {low = 0.5, high = 4.0, log = true}
[[objectives]]
metric = "sag_mm"
[optimizer]
sampler = "random"
trials = 4
batch = 2
seed = 3
[evaluation]
kind = "gravity_sag"
settle_s = 0.2
"""


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _cluster_processes(temp_dir: str) -> list:
    """This cluster's processes: every Ray process names its session folder (under ``temp_dir``) or the temp dir."""
    found = []
    for proc in psutil.process_iter(["pid", "cmdline"]):
        with_dir = any(temp_dir in part for part in (proc.info["cmdline"] or []))
        if with_dir and proc.pid != os.getpid():
            found.append(proc)
    return found


@pytest.fixture(scope="module")
def cluster():
    """(address, token, environment for a driver): a head and a second node on 127.0.0.1, token authentication on."""
    token = secrets.token_hex(32)
    temp_dir = tempfile.mkdtemp(prefix="csray", dir="/tmp")  # short: Ray's socket paths must fit 107 characters
    port = _free_port()
    env = dict(os.environ, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=token, **LOOPBACK)
    env.pop("RAY_AUTH_TOKEN_PATH", None)
    env.pop("RAY_ADDRESS", None)
    helper = subprocess.Popen([sys.executable, "-c", NODES, str(port), temp_dir], env=env, stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True)
    try:
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.append(helper.stdout.readline()), daemon=True)
        reader.start()
        reader.join(90)
        assert lines and lines[0].startswith("READY 127.0.0.1:"), f"the cluster did not start: {lines}"
        address = lines[0].split()[1]
        driver = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
        driver.update(LOOPBACK, PYTHONPATH=str(ROOT), RAY_AUTH_TOKEN=token)
        yield address, token, driver
    finally:
        helper.stdin.close()
        try:
            helper.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(helper.pid, signal.SIGKILL)
            helper.wait(timeout=10)
        deadline = time.monotonic() + 10
        while _cluster_processes(temp_dir) and time.monotonic() < deadline:
            time.sleep(0.2)
        strays = _cluster_processes(temp_dir)
        for proc in strays:  # only this cluster's processes: they name its temp folder
            proc.kill()
        shutil.rmtree(temp_dir, ignore_errors=True)
        assert not strays, f"Ray processes outlived the cluster: {[p.info['cmdline'][:1] for p in strays]}"


def _cli(command: str, spec: Path, out: Path, env: dict, *extra: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "continuum_sim", command, str(spec), "--out", str(out), "--quiet", *extra]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=240)


def _results(records: Path) -> dict[str, tuple]:
    """Each recorded variant's outcome: status, metrics, error (not its timing, host or process)."""
    out = {}
    for path in records.glob("*.json"):
        record = json.loads(path.read_text())
        out[record["variant_id"]] = (record["status"], record["metrics"], record["error"])
    return out


@pytest.mark.parametrize(
    ("command", "text", "records"),
    [("sweep", SWEEP, "records"), ("sensitivity", SENSITIVITY, "records"), ("optimize", OPTIMIZE, "evaluations/records")],
)
def test_a_study_on_the_cluster_matches_the_local_run_with_one_connection(tmp_path, cluster, command, text, records):
    address, _, env = cluster
    spec = tmp_path / f"{command}.toml"
    spec.write_text(text)
    local = _cli(command, spec, tmp_path / "local", env, "--workers", "1")
    assert local.returncode == 0, local.stderr[-2000:]
    remote = _cli(command, spec, tmp_path / "ray", env, "--backend", "ray", "--address", address)
    assert remote.returncode == 0, remote.stderr[-2000:]

    expected = _results(tmp_path / "local" / records)
    assert expected and _results(tmp_path / "ray" / records) == expected
    assert remote.stderr.count("ray: connected to") == 1, remote.stderr  # optimize: 2 generations, one connection
    assert f"ray: connected to {address} (2 CPUs)" in remote.stderr
    # the workers' start-up is reported apart (a study this small may finish before the second worker is up)
    assert "workers ready in" in remote.stderr and "(worker_startup_s; not part of any variant's cost)" in remote.stderr


@pytest.mark.parametrize(("token", "detail"), [("0" * 64, "refused the token from RAY_AUTH_TOKEN"), (None, "no token given")])
def test_a_wrong_or_missing_token_is_one_line_naming_authentication(tmp_path, cluster, token, detail):
    address, _, env = cluster
    env = dict(env, RAY_NUM_REDIS_GET_RETRIES="3")  # Ray retries a refused connection 20 times, 1 s apart
    env.pop("RAY_AUTH_TOKEN")
    if token is not None:
        env["RAY_AUTH_TOKEN"] = token
    spec = tmp_path / "sweep.toml"
    spec.write_text(SWEEP)
    proc = _cli("sweep", spec, tmp_path / "ray", env, "--backend", "ray", "--address", address)
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "authentication failed: set RAY_AUTH_TOKEN or RAY_AUTH_TOKEN_PATH (ray get-auth-token on the head)" in lines[0]
    assert detail in lines[0]
    assert not (tmp_path / "ray").exists()  # refused before the study folder is touched


def test_a_version_mismatch_is_one_line_naming_both_versions(tmp_path, cluster):
    """Ray's own check, fed another Ray version for this process (installing one would take minutes)."""
    address, _, env = cluster
    spec = tmp_path / "sweep.toml"
    spec.write_text(SWEEP)
    driver = ("import sys, ray._private.utils as u; here = u.compute_version_info(); "
              "u.compute_version_info = lambda: ('9.9.9', here[1]); "
              "from continuum_sim.cli import main; sys.exit(main(sys.argv[1:]))")
    cmd = [sys.executable, "-c", driver, "sweep", str(spec), "--out", str(tmp_path / "ray"), "--quiet", "--backend", "ray",
           "--address", address]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    import ray

    assert f"version mismatch: the cluster runs Ray {ray.__version__} on Python " in lines[0]
    assert "this machine Ray 9.9.9 on Python" in lines[0]
