"""A real two-node Ray cluster with token authentication, on loopback: studies through ``--address`` match the local run.

The cluster (a head and a second node, one CPU each) runs in a helper process started by
``scripts/ray_loopback.py``, every address 127.0.0.1 (its servers listen there only), with
``RAY_AUTH_MODE=token`` and a token generated here. Each study connects once, gets the
token through the environment only (``RAY_AUTH_TOKEN``, no ``RAY_AUTH_MODE``: the driver
turns token mode on itself), and records the same results as the local backend; a wrong
or missing token, or another Ray version, is one line naming the cause, exit 2. The helper's nodes are stopped
in a finally, and no process of this cluster may survive.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("ray")
pytest.importorskip("psutil")  # a dependency of ray; the cluster's clean-up finds its processes with it

ROOT = Path(__file__).resolve().parents[1]

# The cluster itself: scripts/ray_loopback.py, which the Ray check and the throughput benchmark also start.
sys.path.insert(0, str(ROOT / "scripts"))
from ray_loopback import loopback_cluster  # noqa: E402

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


@pytest.fixture(scope="module")
def cluster():
    """(address, token, environment for a driver): a head and a second node on 127.0.0.1, token authentication on."""
    with loopback_cluster(cpus_per_node=1, start_timeout=90) as started:
        yield started.address, started.env["RAY_AUTH_TOKEN"], started.env
    assert not started.strays_killed, f"Ray processes outlived the cluster: pids {started.strays_killed}"


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
