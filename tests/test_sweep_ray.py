"""The Ray backend runs the same sweep on an existing cluster, with identical results; its connection errors and worker deaths."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from continuum_sim.sweep import load_spec, run_sweep

ray = pytest.importorskip("ray")

ROOT = Path(__file__).resolve().parents[1]
SPEC = """\
metrics = ["sag_mm", "pcc_error_mm", "min_cable_tension_n"]
[grid]
"model.stiffness_scale" = [0.5, 1.0, 300.0, 4.0]
[evaluation]
kind = "gravity_sag"
settle_s = 0.4
"""


@pytest.fixture(scope="module")
def ray_address():
    """A local Ray instance started (and always shut down) by this test module."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        yield ray.get_runtime_context().gcs_address
    finally:
        ray.shutdown()


def rows(path: Path):
    with path.open() as fh:
        return [{k: v for k, v in row.items() if k != "wall_s"} for row in csv.DictReader(fh)]


def test_ray_backend_on_an_existing_cluster_matches_the_local_run(tmp_path, ray_address):
    spec_path = tmp_path / "ray.toml"
    spec_path.write_text(SPEC)
    local = run_sweep(load_spec(spec_path), tmp_path / "local", workers=2, batch="off", progress=False)
    assert local.n_failed == 1  # the 300x variant diverges, on every backend

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "continuum_sim", "sweep", str(spec_path), "--out", str(tmp_path / "ray"), "--backend", "ray", "--address", ray_address, "--quiet"]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "4 variants (0 already recorded, 4 run, 1 failed; mode process)" in proc.stdout
    assert rows(tmp_path / "ray" / "results.csv") == rows(tmp_path / "local" / "results.csv")
    record = next((tmp_path / "ray" / "records").glob("*.json")).read_text()
    assert '"backend": "ray/process"' in record


VERSION_MISMATCH = (
    "Version mismatch: The cluster was started with:\n    Ray: 2.59.0\n    Python: 3.11.7\n"
    "This process on node 10.0.0.7 was started with:\n    Ray: 2.60.0\n    Python: 3.12.1\n"
)


def test_connection_errors_name_their_cause_in_one_line(monkeypatch):
    from continuum_sim.sweep.backends import connection_error

    monkeypatch.delenv("RAY_AUTH_TOKEN", raising=False)
    monkeypatch.delenv("RAY_AUTH_TOKEN_PATH", raising=False)
    refused = "[W gcs_client.cc:210] Failed to get cluster ID from GCS server: Unauthenticated: RPC error: InvalidAuthToken\n" * 3
    line = connection_error("10.0.0.5:6379", ConnectionError("Failed to connect to Ray cluster at 10.0.0.5:6379"), refused)
    assert "authentication failed: set RAY_AUTH_TOKEN or RAY_AUTH_TOKEN_PATH (ray get-auth-token on the head)" in line
    assert line.endswith("no token given") and "\n" not in line
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", "/secrets/ray_token")
    assert line.replace("no token given", "the cluster refused the token from RAY_AUTH_TOKEN_PATH") == connection_error(
        "10.0.0.5:6379", ConnectionError("Failed to connect"), refused)

    line = connection_error("10.0.0.5:6379", RuntimeError(VERSION_MISMATCH))
    assert "version mismatch: the cluster runs Ray 2.59.0 on Python 3.11.7, this machine Ray 2.60.0 on Python 3.12.1" in line
    assert "\n" not in line

    line = connection_error("10.0.0.5:6379", ConnectionError("Failed to connect"), "2026 INFO worker.py -- Connecting\n[E x] GCS went away\n")
    assert line == "cannot connect to the Ray cluster at '10.0.0.5:6379': ConnectionError: Failed to connect (Ray: [E x] GCS went away)"


def test_a_token_in_the_environment_turns_token_mode_on_for_the_driver_only_while_connected(monkeypatch):
    from continuum_sim.sweep import backends

    monkeypatch.delenv("RAY_AUTH_MODE", raising=False)
    monkeypatch.setenv("RAY_AUTH_TOKEN", "abc")
    session = backends.RaySession(1, None)
    session._auth_mode = backends._token_mode_from_environment()
    assert os.environ["RAY_AUTH_MODE"] == "token"
    session._restore_auth_mode()
    assert "RAY_AUTH_MODE" not in os.environ
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")  # an explicit mode is the user's
    assert backends._token_mode_from_environment() == "disabled" and os.environ["RAY_AUTH_MODE"] == "disabled"


def test_a_variant_that_kills_its_worker_twice_is_recorded_failed_and_the_rest_run_again():
    from continuum_sim.sweep import backends
    from continuum_sim.sweep.spec import Variant

    session = backends.RaySession(2, None, log=lambda line: None)
    replaced: list[int] = []
    session._replace_worker = replaced.append  # no Ray here: the bookkeeping only
    a, b, c = (Variant(i, (("model.stiffness_scale", float(i)),), f"v{i}") for i in range(3))
    queue: list[Variant] = [c]
    deaths: dict[str, int] = {}
    recorded: list[tuple[str, str]] = []
    on_result = lambda variant, result: recorded.append((variant.variant_id, result["status"]))  # noqa: E731
    session._worker_died(0, [a, b], queue, deaths, on_result, RuntimeError("worker died"))
    assert [v.variant_id for v in queue] == ["v2", "v1", "v0"] and not recorded  # a (running) first, then b (queued)
    queue.pop()
    session._worker_died(1, [a], queue, deaths, on_result, RuntimeError("worker died"))
    assert recorded == [("v0", "failed")] and [v.variant_id for v in queue] == ["v2", "v1"] and replaced == [0, 1]


KILL_A_WORKER = """\
import json, os, signal, sys
from continuum_sim.sweep import backends, load_spec

spec = load_spec(sys.argv[1])
statuses, killed, lines = {}, [], []

def on_result(variant, result):
    statuses[variant.variant_id] = [result["status"], result["error"]]
    if not killed:  # SIGKILL the worker that returned the first result: it has the next variant on it
        killed.append(result["pid"])
        os.kill(result["pid"], signal.SIGKILL)

with backends.RaySession(2, sys.argv[2], log=lines.append) as session:
    session.run(spec, spec.variants(), None, on_result)
print(json.dumps({"statuses": statuses, "log": lines}))
"""


def test_a_killed_worker_is_replaced_and_its_variants_run_again(tmp_path, ray_address):
    spec_path = tmp_path / "ray.toml"
    spec_path.write_text(SPEC)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", KILL_A_WORKER, str(spec_path), ray_address], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert sorted(status for status, _ in out["statuses"].values()) == ["failed", "ok", "ok", "ok"], out
    assert all("worker died" not in str(error) for _, error in out["statuses"].values())  # the 300x one diverges, as locally
    assert any(line.startswith("ray: a worker died") for line in out["log"]), out["log"]
    assert out["log"][0].startswith(f"ray: connected to {ray_address} (2 CPUs)")
