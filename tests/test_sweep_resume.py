"""Sweep results folder: kill and resume, failures, table in grid order, plots, refusals."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from continuum_sim import ConfigError
from continuum_sim.sweep import load_spec, run_sweep
from continuum_sim.sweep.store import ResultStore

ROOT = Path(__file__).resolve().parents[1]
METRIC_COLUMNS = ("sag_mm", "pcc_error_mm", "max_cable_tension_n")

# 8 stiffness values plus one (300x) whose explicit hinge springs make the 2 ms step diverge
# (x0.125-x4 of the strain-limited segments; x16 and beyond diverge too).
KILL_SPEC = """\
metrics = ["sag_mm", "pcc_error_mm", "max_cable_tension_n"]

[grid]
"model.stiffness_scale" = [0.125, 0.2, 0.25, 0.4, 0.5, 300.0, 1.0, 2.0, 4.0]

[evaluation]
kind = "gravity_sag"
settle_s = 2.5
"""


def read_table(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def comparable(rows):
    keep = ("index", "variant_id", "model.stiffness_scale", "status", "error", *METRIC_COLUMNS)
    return [{k: row[k] for k in keep} for row in rows]


def sweep_cmd(spec: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "continuum_sim", "sweep", str(spec), "--out", str(out), "--workers", "2", *extra]


def test_killed_sweep_resumes_with_every_variant_exactly_once_and_the_same_values(tmp_path):
    spec_path = tmp_path / "kill.toml"
    spec_path.write_text(KILL_SPEC)
    spec = load_spec(spec_path)
    ids = [v.variant_id for v in spec.variants()]

    # Reference: uninterrupted, in-process, shared-model mode.
    reference = run_sweep(spec, tmp_path / "reference", workers=2, batch="on", progress=False)
    assert reference.n_run == 9 and reference.n_failed == 1
    assert {p.name for p in reference.plots} >= {"sag_mm__vs__model.stiffness_scale.png", "overview__vs__model.stiffness_scale.png"}

    # Killed: one process per variant, SIGKILL to the whole process group once some records exist.
    out = tmp_path / "killed"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(
        sweep_cmd(spec_path, out, "--batch", "off", "--quiet"),
        cwd=ROOT,
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if len(list((out / "records").glob("*.json"))) >= 2:
                break
            time.sleep(0.02)
        assert proc.poll() is None, "the sweep finished before it could be killed"
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    before = {p.name: p.read_bytes() for p in (out / "records").glob("*.json")}
    assert 2 <= len(before) < 9, f"{len(before)} records at the kill"

    resumed = subprocess.run(sweep_cmd(spec_path, out, "--batch", "off", "--quiet"), cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert f"({len(before)} already recorded, {9 - len(before)} run, 1 failed" in resumed.stdout

    records = sorted((out / "records").glob("*.json"))
    assert sorted(p.stem for p in records) == sorted(ids)  # every variant exactly once
    for name, data in before.items():  # finished before the kill: kept, not redone
        assert (out / "records" / name).read_bytes() == data
    rows = read_table(out / "results.csv")
    assert [row["variant_id"] for row in rows] == ids  # grid order, no duplicates
    assert comparable(rows) == comparable(read_table(tmp_path / "reference" / "results.csv"))
    failed = [row for row in rows if row["status"] != "ok"]
    assert len(failed) == 1 and failed[0]["model.stiffness_scale"] == "300.0" and failed[0]["error"].startswith("diverged")
    assert all(row["sag_mm"] == "" for row in failed)

    retried = run_sweep(spec, out, workers=2, retry_failed=True, progress=False)  # only the failed one re-runs
    assert (retried.n_skipped, retried.n_run, retried.n_failed) == (8, 1, 1)


def test_results_folder_table_plots_and_refusals(tmp_path):
    spec_path = tmp_path / "two.toml"
    spec_path.write_text(
        'metrics = ["sag_mm", "max_cable_tension_n"]\n'
        "[grid]\n"
        '"model.stiffness_scale" = [1.0, 2.0, 4.0]\n'
        '"arm.sections.2.hinge_thickness" = [0.0008, 0.0012]\n'
        '[evaluation]\nkind = "gravity_sag"\nsettle_s = 0.2\n'
    )
    spec = load_spec(spec_path)
    out = tmp_path / "out"
    first = run_sweep(spec, out, workers=2, progress=False)
    assert (first.n_variants, first.n_skipped, first.n_run, first.mode) == (6, 0, 6, "shared")
    assert (out / "spec.toml").read_text() == spec_path.read_text()
    rows = read_table(out / "results.csv")
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert [(float(r["model.stiffness_scale"]), float(r["arm.sections.2.hinge_thickness"])) for r in rows][:3] == [
        (1.0, 0.0008),
        (1.0, 0.0012),
        (2.0, 0.0008),
    ]
    record = json.loads((out / "records" / f"{rows[0]['variant_id']}.json").read_text())
    assert record["params"] == {"model.stiffness_scale": 1.0, "arm.sections.2.hinge_thickness": 0.0008}
    assert record["status"] == "ok" and float(rows[0]["sag_mm"]) == record["metrics"]["sag_mm"]
    names = {p.name for p in first.plots}
    assert {"sag_mm__heatmap.png", "sag_mm__vs__model.stiffness_scale.png", "max_cable_tension_n__vs__arm.sections.2.hinge_thickness.png"} <= names
    assert all(p.stat().st_size > 1000 for p in first.plots)

    again = run_sweep(spec, out, workers=2, progress=False)  # nothing left to do
    assert (again.n_skipped, again.n_run) == (6, 0)
    assert read_table(out / "results.csv") == rows

    spec_path.write_text(spec_path.read_text().replace("[1.0, 2.0, 4.0]", "[1.0, 2.0]"))
    with pytest.raises(ConfigError, match="holds a different sweep \\(grid changed\\)"):
        run_sweep(load_spec(spec_path), out, progress=False)
    (tmp_path / "stuff").mkdir()
    (tmp_path / "stuff" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="exists and is not a sweep folder"):
        run_sweep(spec, tmp_path / "stuff", progress=False)
    assert [p.name for p in (tmp_path / "stuff").iterdir()] == ["notes.txt"]
    with ResultStore(tmp_path / "busy").lock(), pytest.raises(ConfigError, match="in use by another running sweep"):
        run_sweep(spec, tmp_path / "busy", progress=False)


def test_parquet_table_when_pyarrow_is_installed(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    spec_path = tmp_path / "p.toml"
    spec_path.write_text('[grid]\n"model.stiffness_scale" = [1.0, 2.0]\n[evaluation]\nkind = "gravity_sag"\nsettle_s = 0.1\n')
    result = run_sweep(load_spec(spec_path), tmp_path / "out", workers=1, progress=False)
    table = pq.read_table(tmp_path / "out" / "results.parquet").to_pydict()
    assert table["model.stiffness_scale"] == [1.0, 2.0]
    assert table["sag_mm"] == [result.records[v]["metrics"]["sag_mm"] for v in table["variant_id"]]
