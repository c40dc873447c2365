"""provenance.json: its shape, the code hash, the git state, and the run and study folders that hold one."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from continuum_sim import provenance
from continuum_sim.params.registry import registry_sha256

HEX64 = re.compile(r"^[0-9a-f]{64}$")
TOP_KEYS = ["schema", "command", "argv", "created_utc", "package", "git", "code_sha256", "hashes", "versions", "machine"]


@pytest.fixture(autouse=True)
def _fresh_caches():
    provenance.clear_caches()
    yield
    provenance.clear_caches()


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def check_shape(doc: dict) -> None:
    """The schema other code renders and checks (continuum_sim/provenance.py)."""
    assert list(doc) == TOP_KEYS
    assert doc["schema"] == 1 and isinstance(doc["command"], str) and doc["command"]
    assert isinstance(doc["argv"], list) and all(isinstance(a, str) for a in doc["argv"])
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", doc["created_utc"])
    assert doc["package"] == {"name": "continuum_sim", "version": doc["package"]["version"]}
    assert isinstance(doc["package"]["version"], str)
    git = doc["git"]
    assert set(git) == {"commit", "dirty", "changed"}
    assert git["commit"] is None or re.fullmatch(r"[0-9a-f]{40}", git["commit"])
    assert git["dirty"] in (True, False, None)
    assert isinstance(git["changed"], list) and len(git["changed"]) <= provenance.MAX_CHANGED
    assert HEX64.match(doc["code_sha256"])
    assert set(doc["hashes"]) == {"config", "registry", "spec"}
    assert all(v is None or HEX64.match(v) for v in doc["hashes"].values())
    assert list(doc["versions"]) == ["python", "mujoco", "numba", "numpy", "scipy", "SALib", "optuna", "dm_control"]
    assert all(v is None or isinstance(v, str) for v in doc["versions"].values())
    assert doc["versions"]["numpy"] and doc["versions"]["mujoco"]  # installed: never null here
    machine = doc["machine"]
    assert set(machine) == {"platform", "cpu", "cpu_count", "threads"}
    assert isinstance(machine["platform"], str) and isinstance(machine["cpu"], str)
    assert machine["cpu_count"] is None or isinstance(machine["cpu_count"], int)
    assert set(machine["threads"]) == {"NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "numba_cpu_name"}


def test_collect_shape_types_and_hashes(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_NUM_THREADS", "3")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    spec = tmp_path / "spec.toml"
    spec.write_bytes(b"a = 1\n")
    doc = provenance.collect("sweep", config_toml="x = 1\n", registry_sha256=registry_sha256(), spec_path=spec)
    check_shape(doc)
    assert doc["command"] == "sweep"
    assert doc["hashes"] == {"config": _sha(b"x = 1\n"), "registry": registry_sha256(), "spec": _sha(b"a = 1\n")}
    assert doc["machine"]["threads"] == {"NUMBA_NUM_THREADS": 3, "OMP_NUM_THREADS": None, "numba_cpu_name": "generic"}
    empty = provenance.collect("run", config_toml=None, registry_sha256=None, spec_path=None)
    assert empty["hashes"] == {"config": None, "registry": None, "spec": None}
    provenance.write(tmp_path, doc)
    assert json.loads((tmp_path / "provenance.json").read_text()) == doc
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # atomic: no temp file left


def test_registry_hash_is_stable_and_covers_the_metadata(monkeypatch):
    import dataclasses

    from continuum_sim.params import registry

    first = registry_sha256()
    assert HEX64.match(first) and registry_sha256() == first
    changed = (dataclasses.replace(registry.REGISTRY[0], source="another source"), *registry.REGISTRY[1:])
    monkeypatch.setattr(registry, "REGISTRY", changed)
    assert registry_sha256() != first


def test_cli_invocation_sets_argv_and_command(monkeypatch):
    provenance.set_invocation(["continuum-sim", "sweep", "spec.toml"], command="sweep")
    try:
        doc = provenance.collect(provenance.current_command("run"), config_toml=None, registry_sha256=None, spec_path=None)
        assert doc["argv"] == ["continuum-sim", "sweep", "spec.toml"] and doc["command"] == "sweep"
    finally:
        provenance.set_invocation(None)
    assert provenance.current_command("run") == "run"


def _fake_package(root: Path) -> Path:
    package = root / "pkg"
    (package / "data").mkdir(parents=True)
    (package / "sub").mkdir()
    (package / "__init__.py").write_text('"""A package."""\n')
    (package / "sub" / "mod.py").write_text("X = 1\n")
    (package / "data" / "scenario.toml").write_text("[a]\nb = 1\n")
    return package


def test_code_hash_follows_the_package_sources_only(tmp_path, monkeypatch):
    package = _fake_package(tmp_path)
    first = provenance.code_sha256(package)
    assert HEX64.match(first) and provenance.code_sha256(package) == first
    # Not part of the code: byte-code caches, other data files.
    (package / "__pycache__").mkdir()
    (package / "__pycache__" / "mod.cpython-311.py").write_text("junk\n")
    (package / "notes.txt").write_text("notes\n")
    provenance.clear_caches()
    assert provenance.code_sha256(package) == first
    (package / "sub" / "mod.py").write_text("X = 2\n")
    assert provenance.code_sha256(package) == first  # cached per process: a sweep hashes once
    provenance.clear_caches()
    second = provenance.code_sha256(package)
    assert second != first
    (package / "data" / "scenario.toml").write_text("[a]\nb = 2\n")
    provenance.clear_caches()
    assert provenance.code_sha256(package) not in (first, second)
    # A renamed file changes it too (the relative path is hashed with the bytes).
    copy = tmp_path / "copy"
    shutil.copytree(package, copy / "pkg")
    provenance.clear_caches()
    assert provenance.code_sha256(copy / "pkg") == provenance.code_sha256(package)
    (copy / "pkg" / "sub" / "mod.py").rename(copy / "pkg" / "sub" / "other.py")
    provenance.clear_caches()
    assert provenance.code_sha256(copy / "pkg") != provenance.code_sha256(package)
    # collect() hashes the package it is pointed at.
    monkeypatch.setattr(provenance, "PACKAGE_ROOT", package)
    provenance.clear_caches()
    assert provenance.collect("run", config_toml=None, registry_sha256=None, spec_path=None)["code_sha256"] == provenance.code_sha256(package)


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@example.org", "-c", "commit.gpgsign=false",
                           *args], check=True, capture_output=True, text=True).stdout


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_git_state_from_a_scratch_repository(tmp_path, monkeypatch):
    repo = tmp_path / "repo"
    package = _fake_package(repo)
    (repo / "pyproject.toml").write_text("[project]\nname = 'pkg'\n")
    (repo / ".gitignore").write_text("__pycache__/\n")
    _git(repo, "init", "-q")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "init")
    head = _git(repo, "rev-parse", "HEAD").strip()
    assert provenance.git_state(package) == {"commit": head, "dirty": False, "changed": []}
    # Output files outside the package (a run folder in the checkout) and ignored caches: still clean.
    (repo / "runs" / "a").mkdir(parents=True)
    (repo / "runs" / "a" / "provenance.json").write_text("{}\n")
    (package / "__pycache__").mkdir()
    (package / "__pycache__" / "x.pyc").write_bytes(b"\0")
    provenance.clear_caches()
    assert provenance.git_state(package)["dirty"] is False
    (package / "sub" / "mod.py").write_text("X = 3\n")
    (package / "new.py").write_text("Y = 1\n")
    assert provenance.git_state(package)["dirty"] is False  # cached per process
    provenance.clear_caches()
    state = provenance.git_state(package)
    assert state["commit"] == head and state["dirty"] is True
    assert sorted(state["changed"]) == ["pkg/new.py", "pkg/sub/mod.py"]
    (repo / "pyproject.toml").write_text("[project]\nname = 'pkg2'\n")
    provenance.clear_caches()
    assert "pyproject.toml" in provenance.git_state(package)["changed"]
    # collect() reads the checkout of the package it is pointed at.
    monkeypatch.setattr(provenance, "PACKAGE_ROOT", package)
    provenance.clear_caches()
    assert provenance.collect("run", config_toml=None, registry_sha256=None, spec_path=None)["git"]["commit"] == head


def test_git_state_is_null_outside_a_checkout_or_without_git(tmp_path, monkeypatch):
    package = _fake_package(tmp_path / "plain")
    assert provenance.git_state(package) == {"commit": None, "dirty": None, "changed": []}
    monkeypatch.setenv("PATH", str(tmp_path / "nowhere"))  # no git at all: still a document, never an error
    monkeypatch.setattr(provenance, "PACKAGE_ROOT", package)
    provenance.clear_caches()
    doc = provenance.collect("run", config_toml=None, registry_sha256=None, spec_path=None)
    check_shape(doc)
    assert doc["git"] == {"commit": None, "dirty": None, "changed": []}


def test_run_folder_holds_provenance(tmp_path):
    """The task's first stage (0.5 s simulated): provenance.json beside config.toml and parameters.json."""
    from continuum_sim.runfolder import RUN_FILES, prepare_run_folder
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import run_scenario

    out = tmp_path / "run"
    run_scenario(ScenarioConfig.default(), out, stages=("initial",), progress=False)
    doc = json.loads((out / "provenance.json").read_text())
    check_shape(doc)
    assert doc["command"] == "run"
    assert doc["hashes"] == {"config": _sha((out / "config.toml").read_bytes()), "registry": registry_sha256(), "spec": None}
    assert doc["code_sha256"] == provenance.code_sha256()
    assert "provenance.json" in RUN_FILES
    prepare_run_folder(out, overwrite=True)  # --overwrite still recognises the folder as a run's
    assert not out.exists() or not any(out.iterdir())


def test_sweep_folder_holds_provenance_with_the_spec_hash(tmp_path):
    from report_helpers import TINY_SWEEP

    from continuum_sim.cli import main

    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY_SWEEP)
    out = tmp_path / "sweep"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    doc = json.loads((out / "provenance.json").read_text())
    check_shape(doc)
    assert doc["command"] == "sweep" and doc["argv"][:3] == ["continuum-sim", "sweep", str(spec)]
    assert doc["hashes"]["spec"] == _sha(spec.read_bytes())
    assert doc["hashes"]["registry"] == registry_sha256() and HEX64.match(doc["hashes"]["config"])
    assert provenance.current_command("run") == "run"  # the CLI call is over: forgotten


def test_study_provenance_without_a_spec_file_hashes_the_spec_text(tmp_path):
    """Sensitivity (and optimise) studies write it through sweep.store.write_provenance, at their start and end."""
    from continuum_sim.sensitivity.spec import load_spec
    from continuum_sim.sweep.store import write_provenance

    spec_path = tmp_path / "tiny.toml"
    text = 'method = "morris"\nparameters = ["model.joint_damping"]\nmetrics = ["sag_mm"]\n[evaluation]\nkind = "gravity_sag"\n'
    spec_path.write_text(text)
    spec = load_spec(spec_path)
    write_provenance(tmp_path / "a", "sensitivity", spec, spec_path)
    write_provenance(tmp_path / "b", "sensitivity", spec, None)
    a, b = (json.loads((tmp_path / n / "provenance.json").read_text()) for n in ("a", "b"))
    check_shape(a)
    assert a["command"] == "sensitivity"
    assert a["hashes"]["spec"] == b["hashes"]["spec"] == _sha(text.encode())
    assert a["hashes"]["config"] == provenance.sha256_text(provenance.config_toml(spec.base))


def test_validation_report_folder_holds_provenance(tmp_path):
    from continuum_sim.cli import main

    out = tmp_path / "rep"
    assert main(["validate", "--quick", "--only", "cosserat.beam", "--no-plots", "--out", str(out)]) == 0
    doc = json.loads((out / "provenance.json").read_text())
    check_shape(doc)
    assert doc["command"] == "validate" and doc["argv"][:2] == ["continuum-sim", "validate"]
    assert doc["hashes"] == {"config": None, "registry": registry_sha256(), "spec": None}
