"""Hostile-input corpus: every command, bad files, bad values, bad paths -> one line and a documented exit code.

Each case runs ``continuum_sim.cli.main(argv)`` in-process and must fail fast, in
validation, before any work: the expected exit code, exactly one line on stderr that
names the field or path, never a traceback. (Signals, pipes and orphan processes need
real processes: tests/test_hostile_proc.py.)
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from continuum_sim.cli import EXIT_USAGE, main
from continuum_sim.configio import dumps_toml, to_dict
from continuum_sim.geometry import ArmGeometry
from continuum_sim.scenario.config import ScenarioConfig

RECORDING_DIR = Path(__file__).resolve().parents[1] / "validation" / "opencr_ftdcr_v4"
RECORDING = str(RECORDING_DIR / "recordings" / "val.recording.csv")  # a real recording (docs/sysid.md)
ROBOT = str(RECORDING_DIR / "ftdcr_v4.toml")


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    """Hostile and valid input files, made once."""
    root = tmp_path_factory.mktemp("hostile")
    paths: dict[str, Path] = {}

    def put(name: str, data: bytes) -> None:
        paths[name] = root / name
        paths[name].write_bytes(data)

    put("binary", bytes(range(256)) * 4)
    put("utf16", "a = 1\n".encode("utf-16"))
    put("latin1", "name = \"caf\xe9\"\n".encode("latin-1"))
    put("deep", ("a = " + "[" * 1000 + "]" * 1000 + "\n").encode())
    put("deep_tables", ("[" + ".".join(["t"] * 200) + "]\nx = 1\n").encode())
    put("bad_toml", b"[model\nstiffness_scale = \n")
    put("huge_value", ("[model]\njoint = \"" + "x" * 100_000 + "\"\n").encode())
    put("nan_section", b"[[sections]]\nlength = nan\n")
    put("timestep", b"[model]\ntimestep = 1e-9\n")
    put("segments200", b"[model]\nsegments_per_section = 200\n")
    put("camera", b"[simulation]\ncameras = [\"overview\", \"no_such_camera\"]\n")
    put("cut_speed", b"cut_speed = 1e-7\n")
    put("scenario_cut_speed", b"[plan]\ncut_speed = 1e-7\n")
    put("unknown_key", b"[model]\nstifness_scale = 2.0\n")
    one = to_dict(ArmGeometry.default())
    one["sections"] = one["sections"][:1]
    put("one_section", dumps_toml(one).encode())
    scenario = to_dict(ScenarioConfig.default())
    scenario["arm"]["sections"] = scenario["arm"]["sections"][:1]
    put("one_section_scenario", dumps_toml(scenario).encode())  # a scenario TOML, as `run --config` takes
    paths["folder"] = root / "folder.toml"
    paths["folder"].mkdir()
    paths["fifo"] = root / "fifo.toml"
    os.mkfifo(paths["fifo"])
    paths["missing"] = root / "missing.toml"
    paths["a_file"] = root / "a_file"
    paths["a_file"].write_text("not a folder\n")
    put("empty_csv", b"")
    put("garbage_csv", b"a,b\n1,2\n")
    for name, config, trajectory in (("bad_run", bytes(range(256)), b"x"),
                                     ("damaged_run", b"[model]\nstiffness_scale = 1.0\n", b"PK\x03\x04 truncated")):
        paths[name] = root / name
        paths[name].mkdir()
        (paths[name] / "config.toml").write_bytes(config)
        (paths[name] / "trajectory.npz").write_bytes(trajectory)
    # sweep specs
    put("spec_stage_typo", b'[grid]\n"model.stiffness_scale" = [1.0, 2.0]\n[evaluation]\nkind = "stage"\nstage = "miling"\n')
    put("spec_overlap", b'[grid]\n"model.segments_per_section" = [10, 100]\n[evaluation]\nkind = "gravity_sag"\n')
    put("spec_timestep", b'[grid]\n"model.timestep" = [0.004, 1e-9]\n[evaluation]\nkind = "scenario"\n')
    put("spec_too_big", b'[grid]\n"model.stiffness_scale" = {start = 1, stop = 2, num = 1000}\n'
        b'"model.joint_damping" = {start = 0.1, stop = 1, num = 1000}\n[evaluation]\nkind = "gravity_sag"\n')
    put("spec_ok", b'[grid]\n"model.stiffness_scale" = [1.0, 2.0]\n[evaluation]\nkind = "gravity_sag"\n')
    put("spec_bad_kind", b'[grid]\n"model.stiffness_scale" = [1.0]\n[evaluation]\nkind = "gravity"\n')
    put("spec_bad_path", b'[grid]\n"model.stifness_scale" = [1.0]\n[evaluation]\nkind = "gravity_sag"\n')
    # every value valid alone; only timestep 2e-5 s at 40 Hz asks 1250 steps per tick (> 1000): variant 3 of 2x2x600
    put("spec_combination", b'[grid]\n"model.timestep" = [0.004, 2e-5]\n"control.rate_hz" = [125.0, 40.0]\n'
        b'"plan.cut_speed" = {start = 0.001, stop = 0.002, num = 600}\n[evaluation]\nkind = "scenario"\n')
    return {k: str(v) for k, v in paths.items()}


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line(err: str, *fragments: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert len(lines[0]) <= 460, lines[0]  # MAX_LINE + the "continuum-sim <command>: " prefix
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


BAD_FILES = {  # file key -> what the one line must say
    "binary": "not UTF-8",
    "utf16": "UTF-16",
    "latin1": "not UTF-8",
    "deep": "nested too deeply",
    "deep_tables": "nested too deeply",
    "bad_toml": "invalid TOML",
    "folder": "is a folder",
    "fifo": "not a regular file",
    "missing": "file not found",
}

# Every command that reads a TOML file, with the option naming it.
FILE_OPTIONS = [
    ("fk", ["fk", "0", "0", "0", "0", "0", "0", "--config"]),
    ("ik", ["ik", "--position", "0", "0", "0.4", "--config"]),
    ("ik-layout", ["ik", "--position", "0", "0", "0.4", "--arm", "left", "--layout"]),
    ("plan-config", ["plan", "--no-plots", "--config"]),
    ("plan-layout", ["plan", "--no-plots", "--layout"]),
    ("plan-plan", ["plan", "--no-plots", "--plan"]),
    ("workspace", ["workspace", "--samples", "100", "--config"]),
    ("run", ["run", "--quiet", "--config"]),
    ("build-model", ["build-model", "--models-only", "--config"]),
    ("sweep", ["sweep"]),
    ("replay", ["replay", RECORDING, "--config"]),
    ("identify", ["identify", RECORDING, "--fit", "model.stiffness_scale", "--config"]),
    ("synthesize", ["synthesize", "--duration", "1", "--config"]),
]


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
@pytest.mark.parametrize("command, argv", FILE_OPTIONS, ids=[c for c, _ in FILE_OPTIONS])
def test_bad_file_is_one_line_exit_2(command, argv, kind, files, tmp_path, capsys):
    full = [*argv, files[kind]]
    if command not in ("fk", "ik", "ik-layout"):
        full += ["--out", str(tmp_path / "out")]
    code, _, err = run_cli(full, capsys)
    assert code == EXIT_USAGE, err
    assert_one_line(err, BAD_FILES[kind], Path(files[kind]).name)
    assert not (tmp_path / "out").exists()  # refused before anything was written


OUT_COMMANDS = [
    ("plan", ["plan", "--no-plots"]),
    ("workspace", ["workspace", "--samples", "100"]),
    ("run", ["run", "--quiet"]),
    ("build-model", ["build-model", "--models-only"]),
    ("sweep", ["sweep", "SPEC"]),
    ("validate", ["validate", "--only", "beam.section"]),
    ("replay", ["replay", RECORDING, "--config", ROBOT]),
    ("identify", ["identify", RECORDING, "--config", ROBOT, "--fit", "model.stiffness_scale", "--max-nfev", "1"]),
]


def _bad_outs(files: dict[str, str]) -> dict[str, tuple[str, str]]:
    return {
        "empty": ("", "empty string"),
        "blank": ("   ", "empty string"),
        "proc": ("/proc/continuum_sim_out", "/proc"),
        "sys": ("/sys/kernel/continuum_sim_out", "/sys"),
        "existing_file": (files["a_file"], "is not a folder"),
        "under_a_file": (files["a_file"] + "/sub", "is a file|Not a directory"),
        "long_name": (str(Path(files["a_file"]).parent / ("x" * 300)), "at most 255"),
        "long_path": ("/tmp/" + "/".join(["y" * 200] * 25), "at most 4095"),
    }


@pytest.mark.parametrize("bad", ["empty", "blank", "proc", "sys", "existing_file", "under_a_file", "long_name", "long_path"])
@pytest.mark.parametrize("command, argv", OUT_COMMANDS, ids=[c for c, _ in OUT_COMMANDS])
def test_bad_out_is_refused_before_work(command, argv, bad, files, capsys):
    out, fragment = _bad_outs(files)[bad]
    full = [files["spec_ok"] if a == "SPEC" else a for a in argv] + ["--out", out]
    code, _, err = run_cli(full, capsys)
    assert code == EXIT_USAGE, err
    assert_one_line(err, "--out")
    assert any(alternative in err for alternative in fragment.split("|")), err


CASES = [  # (id, argv with {file} placeholders, exit code, fragments of the one line)
    ("fk-nan", ["fk", "nan", "0", "0", "0", "0", "0"], 2, ["Q", "finite"]),
    ("fk-inf", ["fk", "0", "0", "inf", "0", "0", "0"], 2, ["finite"]),
    ("fk-word", ["fk", "zero", "0", "0", "0", "0", "0"], 2, ["invalid float value"]),
    ("fk-too-few", ["fk", "0.1", "0"], 2, ["expected 6 values"]),
    ("fk-too-many", ["fk", *["0"] * 8], 2, ["expected 6 values"]),
    ("fk-bend-limit", ["fk", "3", "0", "0", "0", "0", "0"], 2, ["θ0"]),
    ("fk-huge-arg", ["fk", "1" * 100_000, "0", "0", "0", "0", "0"], 2, ["finite"]),
    ("fk-one-section-wrong-count", ["fk", *["0.1"] * 6, "--config", "{one_section}"], 2, ["expected 2 values"]),
    ("fk-one-section-scenario-wrong-count", ["fk", *["0.1"] * 6, "--config", "{one_section_scenario}"], 2,
     ["expected 2 values", "1 sections", "one_section_scenario"]),
    ("fk-nan-in-file", ["fk", "0", "0", "--config", "{nan_section}"], 2, ["sections[0].length", "finite"]),
    ("fk-unknown-option", ["fk", "0", "0", "0", "0", "0", "0", "--bogus"], 2, ["unrecognized arguments"]),
    ("no-command", [], 2, ["required"]),
    ("unknown-command", ["fly"], 2, ["invalid choice"]),
    ("ik-no-target", ["ik"], 2, ["--position"]),
    ("ik-position-huge", ["ik", "--position", "1e300", "0", "0.3"], 2, ["--position", "100"]),
    ("ik-position-nan", ["ik", "--position", "nan", "0", "0.3"], 2, ["--position", "finite"]),
    ("ik-k1-huge", ["ik", "--k1", "1e300", "--position", "0", "0", "0.4"], 2, ["--k1"]),
    ("ik-k2-negative", ["ik", "--k2", "-1", "--position", "0", "0", "0.4"], 2, ["--k2"]),
    ("ik-tol-zero", ["ik", "--tol", "0", "--position", "0", "0", "0.4"], 2, ["--tol"]),
    ("ik-tol-inf", ["ik", "--tol", "inf", "--position", "0", "0", "0.4"], 2, ["--tol", "finite"]),
    ("ik-rotvec-huge", ["ik", "--position", "0", "0", "0.4", "--rotvec", "1e20", "0", "0"], 2, ["--rotvec"]),
    ("ik-both-orientations", ["ik", "--position", "0", "0", "0.4", "--rotvec", "0", "0", "0", "--zaxis", "0", "0", "1"], 2,
     ["exclusive"]),
    ("ik-zaxis-zero", ["ik", "--position", "0", "0", "0.4", "--zaxis", "0", "0", "0"], 2, ["--zaxis"]),
    ("ik-matrix-not-json", ["ik", "--matrix", "[[1, 2"], 2, ["--matrix"]),
    ("ik-matrix-shape", ["ik", "--matrix", "[[1]]"], 2, ["--matrix", "shape"]),
    ("ik-matrix-deep", ["ik", "--matrix", "[" * 100_000 + "]" * 100_000], 2, ["--matrix"]),
    ("ik-matrix-strings", ["ik", "--matrix", json.dumps([["a"] * 4] * 4)], 2, ["--matrix"]),
    ("ik-q0-count", ["ik", "--position", "0", "0", "0.4", "--q0", "1", "2"], 2, ["--q0", "expected 6"]),
    ("ik-tool-bad", ["ik", "--position", "0", "0", "0.4", "--tool", "hammer"], 2, ["--tool"]),
    ("ik-unreachable", ["ik", "--position", "0", "0", "0.9"], 1, ["outside the workspace"]),
    ("plan-cut-speed", ["plan", "--no-plots", "--plan", "{cut_speed}", "--out", "{tmp}/p"], 2,
     ["plan:", "samples", "cut_speed"]),
    ("plan-unknown-key", ["plan", "--no-plots", "--plan", "{unknown_key}", "--out", "{tmp}/p"], 2, ["model"]),
    ("workspace-samples", ["workspace", "--samples", "-1", "--out", "{tmp}/w"], 2, ["samples"]),
    ("workspace-nan-in-file", ["workspace", "--config", "{nan_section}", "--out", "{tmp}/w"], 2, ["sections[0].length", "finite"]),
    ("workspace-voxel-nan", ["workspace", "--voxel", "nan", "--out", "{tmp}/w"], 2, ["--voxel", "finite"]),
    ("workspace-section-nan", ["workspace", "--section-y", "nan", "--out", "{tmp}/w"], 2, ["--section-y", "finite"]),
    ("workspace-section-inf", ["workspace", "--section-y", "-inf", "--out", "{tmp}/w"], 2, ["--section-y"]),
    ("workspace-seed-word", ["workspace", "--seed", "x", "--out", "{tmp}/w"], 2, ["--seed"]),
    ("run-timestep", ["run", "--quiet", "--config", "{timestep}", "--out", "{tmp}/r"], 2,
     ["model.timestep", "steps per control tick"]),
    ("run-segments-200", ["run", "--quiet", "--config", "{segments200}", "--out", "{tmp}/r"], 2,
     ["model.segments_per_section", "overlap"]),
    ("run-camera", ["run", "--quiet", "--video", "--config", "{camera}", "--out", "{tmp}/r"], 2,
     ["simulation.cameras[1]", "no_such_camera"]),
    ("run-cut-speed", ["run", "--quiet", "--config", "{scenario_cut_speed}", "--out", "{tmp}/r"], 2, ["plan", "samples"]),
    ("run-huge-value", ["run", "--quiet", "--config", "{huge_value}", "--out", "{tmp}/r"], 2, ["model.joint", "characters"]),
    ("run-unknown-key", ["run", "--quiet", "--config", "{unknown_key}", "--out", "{tmp}/r"], 2,
     ["model.stifness_scale", "unknown key"]),
    ("run-control-bad", ["run", "--control", "half"], 2, ["--control"]),
    ("run-controller-no-module", ["run", "--quiet", "--controller", "nosuch.module:Thing", "--out", "{tmp}/r"], 2,
     ["control.controller", "nosuch"]),
    ("run-controller-no-class", ["run", "--quiet", "--controller", "continuum_sim.controllers:Nope", "--out", "{tmp}/r"], 2,
     ["control.controller", "Nope"]),
    ("run-controller-syntax", ["run", "--quiet", "--controller", "justaword", "--out", "{tmp}/r"], 2,
     ["control.controller", "package.module:ClassName"]),
    ("run-controller-not-a-controller", ["run", "--quiet", "--controller", "os:getcwd", "--out", "{tmp}/r"], 2,
     ["control.controller", "Controller protocol"]),
    ("build-segments-200", ["build-model", "--models-only", "--config", "{segments200}", "--out", "{tmp}/m"], 2,
     ["model.segments_per_section"]),
    ("sweep-stage-typo", ["sweep", "{spec_stage_typo}", "--out", "{tmp}/s"], 2, ["evaluation.stage", "milling"]),
    ("sweep-overlap", ["sweep", "{spec_overlap}", "--out", "{tmp}/s"], 2, ["model.segments_per_section", "variant 1"]),
    ("sweep-timestep", ["sweep", "{spec_timestep}", "--out", "{tmp}/s"], 2, ["model.timestep", "variant 1"]),
    ("sweep-too-big", ["sweep", "{spec_too_big}", "--out", "{tmp}/s"], 2, ["1000000 variants"]),
    ("sweep-bad-kind", ["sweep", "{spec_bad_kind}", "--out", "{tmp}/s"], 2, ["evaluation.kind"]),
    ("sweep-bad-path", ["sweep", "{spec_bad_path}", "--out", "{tmp}/s"], 2, ["stifness_scale"]),
    ("sweep-combination-only", ["sweep", "{spec_combination}", "--out", "{tmp}/s"], 2,
     ["model.timestep", "1250 MuJoCo steps", "variant 1800", "control.rate_hz = 40.0"]),
    ("sweep-workers-0", ["sweep", "{spec_ok}", "--workers", "0", "--out", "{tmp}/s"], 2, ["--workers"]),
    ("sweep-address-local", ["sweep", "{spec_ok}", "--address", "127.0.0.1:1", "--out", "{tmp}/s"], 2, ["--address"]),
    ("sweep-address-refused", ["sweep", "{spec_ok}", "--backend", "ray", "--address", "127.0.0.1:1", "--out", "{tmp}/s"], 2,
     ["--address", "cannot reach"]),
    ("sweep-address-garbage", ["sweep", "{spec_ok}", "--backend", "ray", "--address", "no-port", "--out", "{tmp}/s"], 2,
     ["--address", "host:port"]),
    ("sweep-batch-on-ray", ["sweep", "{spec_ok}", "--backend", "ray", "--batch", "on", "--out", "{tmp}/s"], 2, ["--batch"]),
    ("view-no-display", ["view"], 1, ["no display"]),
    # commands added this round (metrics, validate, replay, synthesize, identify)
    ("metrics-missing", ["metrics", "{tmp}/nowhere"], 2, ["RUN_DIR", "config.toml"]),
    ("metrics-file", ["metrics", "{a_file}"], 2, ["RUN_DIR"]),
    ("metrics-empty-arg", ["metrics", ""], 2, ["RUN_DIR"]),
    ("metrics-binary-files", ["metrics", "{bad_run}"], 2, ["bad_run"]),
    ("metrics-damaged-trajectory", ["metrics", "{damaged_run}"], 2, ["trajectory.npz", "not a readable trajectory"]),
    ("validate-unknown-check", ["validate", "--only", "bogus", "--out", "{tmp}/v"], 2, ["--only", "bogus"]),
    ("validate-no-such-option", ["validate", "--fast"], 2, ["unrecognized arguments"]),
    ("replay-missing", ["replay", "{missing}", "--out", "{tmp}/r"], 2, ["missing.toml", "cannot read"]),
    ("replay-folder", ["replay", "{folder}", "--out", "{tmp}/r"], 2, ["folder.toml"]),
    ("replay-binary", ["replay", "{binary}", "--out", "{tmp}/r"], 2, ["binary"]),
    ("replay-utf16", ["replay", "{utf16}", "--out", "{tmp}/r"], 2, ["UTF-8"]),
    ("replay-empty", ["replay", "{empty_csv}", "--out", "{tmp}/r"], 2, ["no header"]),
    ("replay-garbage", ["replay", "{garbage_csv}", "--out", "{tmp}/r"], 2, ["missing column"]),
    ("replay-settle-nan", ["replay", RECORDING, "--settle-s", "nan", "--out", "{tmp}/r"], 2, ["--settle-s", "finite"]),
    ("replay-settle-negative", ["replay", RECORDING, "--config", ROBOT, "--settle-s", "-1", "--out", "{tmp}/r"], 2,
     ["settle_s"]),
    ("replay-mode-bad", ["replay", RECORDING, "--mode", "fast"], 2, ["--mode"]),
    ("synthesize-no-out", ["synthesize"], 2, ["--out"]),
    ("synthesize-out-folder", ["synthesize", "--out", "{folder}"], 2, ["--out", "folder"]),
    ("synthesize-out-proc", ["synthesize", "--out", "/proc/x.csv"], 2, ["--out", "/proc"]),
    ("synthesize-set-no-equals", ["synthesize", "--set", "bogus", "--out", "{tmp}/s.csv"], 2, ["--set", "PATH=VALUE"]),
    ("synthesize-set-unknown", ["synthesize", "--set", "model.nope=1", "--out", "{tmp}/s.csv"], 2, ["model.nope"]),
    ("synthesize-set-word", ["synthesize", "--set", "model.stiffness_scale=abc", "--out", "{tmp}/s.csv"], 2, ["not a number"]),
    ("synthesize-noise-negative", ["synthesize", "--noise-mm", "-1", "--out", "{tmp}/s.csv"], 2, ["--noise-mm"]),
    ("synthesize-noise-nan", ["synthesize", "--noise-deg", "nan", "--out", "{tmp}/s.csv"], 2, ["--noise-deg", "finite"]),
    ("synthesize-duration-huge", ["synthesize", "--duration", "1e9", "--out", "{tmp}/s.csv"], 2, ["--duration"]),
    ("synthesize-amplitude", ["synthesize", "--amplitude", "5", "--out", "{tmp}/s.csv"], 2, ["--amplitude"]),
    ("synthesize-settle-huge", ["synthesize", "--settle-s", "1e9", "--out", "{tmp}/s.csv"], 2, ["settle_s"]),
    ("identify-fit-unknown", ["identify", RECORDING, "--config", ROBOT, "--fit", "bogus", "--out", "{tmp}/i"], 2, ["--fit bogus"]),
    ("identify-fit-bounds", ["identify", RECORDING, "--config", ROBOT, "--fit", "model.stiffness_scale=2:1", "--out", "{tmp}/i"],
     2, ["LOW < HIGH"]),
    ("identify-nfev-0", ["identify", RECORDING, "--config", ROBOT, "--fit", "model.stiffness_scale", "--max-nfev", "0",
                         "--out", "{tmp}/i"], 2, ["--max-nfev"]),
    ("identify-stride-0", ["identify", RECORDING, "--config", ROBOT, "--fit", "model.stiffness_scale", "--stride", "0",
                           "--out", "{tmp}/i"], 2, ["--stride"]),
    ("identify-workers-0", ["identify", RECORDING, "--config", ROBOT, "--fit", "model.stiffness_scale", "--workers", "0",
                            "--out", "{tmp}/i"], 2, ["--workers"]),
    ("identify-missing", ["identify", "{missing}", "--out", "{tmp}/i"], 2, ["cannot read"]),
]


@pytest.mark.parametrize("argv, code, fragments", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_corpus(argv, code, fragments, files, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    full = [a.format(tmp=tmp_path, **files) if "{" in a and "}" in a and not a.startswith("[") else a for a in argv]
    got, _, err = run_cli(full, capsys)
    assert got == code, err
    assert_one_line(err, *fragments)
    for name in ("r", "s", "p", "w", "m", "v", "i", "s.csv"):
        assert not (tmp_path / name).exists() or code == 1  # nothing written by a refused command


def test_fk_takes_a_one_section_arm(files, capsys):
    code, out, err = run_cli(["fk", "0.3", "0.1", "--config", files["one_section"], "--json"], capsys)
    assert code == 0, err
    result = json.loads(out)
    assert len(result["q_rad"]) == 2 and len(result["cable_lengths_m"]) == 3


def test_fk_takes_a_one_section_scenario(files, capsys):
    code, out, err = run_cli(["fk", "0.3", "0.1", "--config", files["one_section_scenario"], "--json"], capsys)
    assert code == 0, err
    result = json.loads(out)
    assert len(result["q_rad"]) == 2 and len(result["cable_lengths_m"]) == 3


def test_fk_help_says_two_values_per_section(capsys):
    code, out, _ = run_cli(["fk", "--help"], capsys)
    assert code == 0 and "2 values per section" in " ".join(out.split()) and "scenario TOML" in out


@pytest.mark.parametrize("backend, fragments", [
    ("osmesa", ["MUJOCO_GL=osmesa: OSMesa not found", "apt-get install libosmesa6", "or use MUJOCO_GL=egl"]),
    ("egl", ["MUJOCO_GL=egl: EGL not found", "libegl1"]),
    ("disable", ["MUJOCO_GL=disable", "switched off"]),
])
def test_video_without_its_gl_library_is_one_line_before_work(backend, fragments, monkeypatch, tmp_path, capsys):
    from continuum_sim import glbackend

    monkeypatch.setattr(glbackend, "library_found", lambda name: name == ("egl" if backend == "osmesa" else "none"))
    monkeypatch.setenv("MUJOCO_GL", backend)
    code, _, err = run_cli(["run", "--video", "--quiet", "--out", str(tmp_path / "r")], capsys)
    assert code == EXIT_USAGE
    assert_one_line(err, *fragments)
    assert not (tmp_path / "r").exists()  # nothing half-written
    assert os.environ["MUJOCO_GL"] == backend  # main() leaves the environment as it found it


def test_mujoco_gl_bogus_is_one_line_before_work(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("MUJOCO_GL", "bogus")
    code, _, err = run_cli(["run", "--quiet", "--out", str(tmp_path / "r")], capsys)
    assert code == EXIT_USAGE
    assert_one_line(err, "MUJOCO_GL", "egl")
    assert not (tmp_path / "r").exists()


def test_help_exits_0(capsys):
    code, out, _ = run_cli(["--help"], capsys)
    assert code == 0 and "run" in out


def test_ik_overflow_warnings_are_one_line(capsys):
    # Far outside the reach but inside the accepted range: the solver may overflow internally; at most one warning line.
    code, out, err = run_cli(["ik", "--position", "99", "-99", "99", "--k1", "1e6"], capsys)
    assert code in (1, 2)
    assert "Traceback" not in err and "RuntimeWarning" not in err.split("\n", 1)[-1]
    assert len([line for line in err.splitlines() if line.strip()]) <= 2


def test_internal_error_is_one_line_and_debug_shows_traceback(monkeypatch, capsys):
    import continuum_sim.cli as cli

    def boom(args):
        raise RuntimeError("x" * 10_000)

    monkeypatch.setattr(cli.parser, "_cmd_fk", boom)
    code, _, err = run_cli(["fk", *["0"] * 6], capsys)
    assert code == cli.EXIT_INTERNAL
    assert_one_line(err, "internal error", "--debug")
    code, _, err = run_cli(["fk", *["0"] * 6, "--debug"], capsys)
    assert code == cli.EXIT_INTERNAL and "Traceback" in err


@pytest.mark.parametrize(
    "exc, code, fragment",
    [
        (KeyboardInterrupt(), 130, "interrupted"),
        (MemoryError(), 4, "out of memory"),
        (OSError(28, "No space left on device", "/x/metrics.json"), 4, "No space left"),
        (PermissionError(13, "Permission denied", "/x/out"), 2, "Permission denied"),
        (RecursionError(), 2, "nested too deeply"),
    ],
    ids=["ctrl-c", "memory", "disk-full", "permission", "recursion"],
)
def test_boundary_maps_failures_to_documented_codes(exc, code, fragment, monkeypatch, capsys):
    import continuum_sim.cli as cli

    def raise_it(args):
        raise exc

    monkeypatch.setattr(cli.parser, "_cmd_fk", raise_it)
    got, _, err = run_cli(["fk", *["0"] * 6], capsys)
    assert got == code
    assert_one_line(err, fragment)


def test_divergence_maps_to_3(monkeypatch, capsys):
    import continuum_sim.cli as cli

    class SimulationDiverged(RuntimeError):
        pass

    def diverge(args):
        raise SimulationDiverged("simulation diverged: non-finite state at t = 0.0160 s")

    monkeypatch.setattr(cli.parser, "_cmd_fk", diverge)
    code, _, err = run_cli(["fk", *["0"] * 6], capsys)
    assert code == cli.EXIT_DIVERGED
    assert_one_line(err, "diverged")


def test_unreadable_file_is_one_line(files, monkeypatch):
    from continuum_sim.configio import ConfigError, load_toml

    def denied(self):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(Path, "read_bytes", denied)
    with pytest.raises(ConfigError, match="permission denied"):
        load_toml(files["spec_ok"])


def test_read_only_out_is_refused(tmp_path, monkeypatch):
    from continuum_sim.configio import ConfigError, check_output_dir

    monkeypatch.setattr(os, "access", lambda path, mode: False)  # as root every folder is writable
    with pytest.raises(ConfigError, match="not writable"):
        check_output_dir(tmp_path / "ro" / "out")


def test_deep_models_get_a_deeper_recursion_limit(monkeypatch, capsys):
    # 200 segments per section (documented maximum) nest 600+ MJCF bodies; dm_control's XML writer
    # recurses per body and hit Python's default limit of 1000 (measured: build-model with
    # [arm] disk_thickness = 0.0005, [model] segments_per_section = 200 now builds, 22 s CPU).
    import sys

    import continuum_sim.cli as cli

    seen = {}
    monkeypatch.setattr(cli.parser, "_cmd_fk", lambda args: seen.setdefault("limit", sys.getrecursionlimit()) and 0)
    before = sys.getrecursionlimit()
    assert main(["fk", *["0"] * 6]) == 0
    assert seen["limit"] >= 10_000 and sys.getrecursionlimit() == before


def test_large_grid_is_checked_quickly_and_still_catches_a_bad_combination():
    import time

    from continuum_sim.configio import ConfigError
    from continuum_sim.sweep.spec import parse_spec

    grid = {"model.stiffness_scale": {"start": 0.5, "stop": 2.0, "num": 1000}, "plan.cut_speed": {"start": 0.001, "stop": 0.01, "num": 100}}
    start = time.process_time()
    spec = parse_spec({"grid": grid, "evaluation": {"kind": "stage", "stage": "milling"}})
    assert spec.n_variants == 100_000 and time.process_time() - start < 15.0  # was ~9 CPU minutes, one variant at a time
    bad = {"model.segments_per_section": [10, 100], "plan.cut_speed": {"start": 0.001, "stop": 0.01, "num": 1500}}
    with pytest.raises(ConfigError, match=r"model\.segments_per_section.*overlap.*variant 1500"):
        parse_spec({"grid": bad, "evaluation": {"kind": "gravity_sag"}})


@pytest.mark.parametrize("address, fragment", [("256.1.1.1:6379", "cannot"), ("localhost:1", "cannot reach"),
                                               ("[::1]:99999", "host:port"), ("ray://:10001", "host:port")])
def test_ray_address_probe_is_bounded(address, fragment):
    import time

    from continuum_sim.configio import ConfigError
    from continuum_sim.sweep.backends import probe_address

    start = time.monotonic()
    with pytest.raises(ConfigError, match=fragment):
        probe_address(address, timeout=2.0)
    assert time.monotonic() - start < 10.0


def test_steps_per_run_limit_names_the_timestep():
    import dataclasses

    from continuum_sim.configio import ConfigError
    from continuum_sim.limits import MAX_SIM_STEPS, check_run_length, check_scenario
    from continuum_sim.scenario.config import ScenarioConfig

    config = ScenarioConfig()
    check_scenario(config)
    check_run_length(config, 51.3)  # the default task: ~13,000 steps
    slow = dataclasses.replace(config, model=dataclasses.replace(config.model, timestep=1e-6))
    with pytest.raises(ConfigError, match=r"model\.timestep.*MuJoCo steps"):
        check_run_length(slow, 1.01 * MAX_SIM_STEPS * 1e-6)


@pytest.mark.parametrize("signal_exc, code, fragment", [(KeyboardInterrupt(), 130, "interrupted"), ("terminated", 143, "terminated")])
def test_signal_inside_a_compiled_function_keeps_its_exit_code(signal_exc, code, fragment, monkeypatch, capsys):
    """Ctrl-C/SIGTERM landing while a numba function runs surfaces as SystemError("... returned a result with an
    exception set") caused by the real exception (seen: SIGTERM during the planner's plan_sample gave exit 70)."""
    import continuum_sim.cli as cli
    from continuum_sim.cli.errors import Terminated

    cause = Terminated() if signal_exc == "terminated" else signal_exc

    def compiled_call(args):
        raise SystemError("CPUDispatcher(<function plan_sample>) returned a result with an exception set") from cause

    monkeypatch.setattr(cli.parser, "_cmd_fk", compiled_call)
    got, _, err = run_cli(["fk", *["0"] * 6], capsys)
    assert got == code
    assert_one_line(err, fragment)
