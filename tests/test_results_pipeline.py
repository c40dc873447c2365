"""The published-results pipeline: code fingerprints and the stale check (scripts/results.py, dvc.yaml)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
import results  # noqa: E402


def test_code_hash_ignores_docstrings_and_comments_but_not_code(tmp_path):
    a = tmp_path / "a.py"
    a.write_text('"""Module doc."""\n\ndef f(x):\n    """What f does."""\n    return x + 1  # one more\n')
    base = results.code_hash(a)
    a.write_text('"""Reworded module doc."""\n\n\ndef f(x):\n    """Reworded."""\n    # a comment\n    return x + 1\n')
    assert results.code_hash(a) == base
    a.write_text('"""Module doc."""\n\ndef f(x):\n    """What f does."""\n    return x + 2\n')
    assert results.code_hash(a) != base


def test_physics_group_is_the_import_closure_of_the_scenario():
    import tomllib

    spec = tomllib.loads((ROOT / "pipeline" / "groups.toml").read_text())["group"]["physics"]
    mods = results.closure(spec["entries"], spec["exclude"], results.module_files())
    # what a run computes with is in; pictures and the registry's metadata are not
    for needed in ("continuum_sim.plant.cutter", "continuum_sim.model.scene", "continuum_sim.control.kernels",
                   "continuum_sim.scenario.metrics", "continuum_sim.toolpath.planner", "continuum_sim.configio"):
        assert needed in mods
    for left_out in ("continuum_sim.scenario.plots", "continuum_sim.video", "continuum_sim.params.registry"):
        assert left_out not in mods


def _scratch_copy(dest: Path) -> Path:
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout.decode().split("\0")
    for rel in filter(None, files):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    return dest


def _status(root: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "scripts/results.py", "status"], cwd=root, capture_output=True, text=True, timeout=300)


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs the git checkout to list the tracked files")
def test_changing_a_default_names_the_stale_results_without_running_them(tmp_path):
    root = _scratch_copy(tmp_path / "repo")
    before = _status(root)
    assert before.returncode == 0, before.stdout + before.stderr
    assert "0 stale" in before.stdout
    defaults = root / "continuum_sim" / "data" / "scenario.toml"
    text = defaults.read_text()
    assert "mu = 0.15" in text
    defaults.write_text(text.replace("mu = 0.15", "mu = 0.2", 1))
    after = _status(root)
    assert after.returncode == 1, after.stdout + after.stderr
    # the studies and tables made with the defaults are named, with the pages that quote them
    for name in ("docs/sensitivity/quick_open", "docs/optimize/task_tpe", "docs/calibration/paper_result_open",
                 "docs/results/default_runs.json"):
        assert name in after.stdout
    assert "README.md" in after.stdout
    # nothing ran: no output changed, no run folder appeared
    assert not (root / "runs").exists()
    assert (root / "docs" / "results" / "default_runs.json").read_bytes() == (ROOT / "docs" / "results" / "default_runs.json").read_bytes()


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs the git checkout to list the tracked files")
def test_a_docstring_edit_stales_nothing_but_a_code_edit_does(tmp_path):
    root = _scratch_copy(tmp_path / "repo")
    module = root / "continuum_sim" / "plant" / "spindle.py"
    text = module.read_text()
    module.write_text(text.replace('"""', '"""Reworded. ', 1))
    assert _status(root).returncode == 0
    module.write_text(text + "\n_UNUSED_BUT_NEW = 1\n")
    out = _status(root)
    assert out.returncode == 1 and "default-runs" in out.stdout and "physics" in out.stdout
