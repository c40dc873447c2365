"""report.html of run and study folders, `continuum-sim report`/`export --rerun`, `run`'s outcome line and --require-completed."""

from __future__ import annotations

import argparse
import base64
import csv
import json
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from report_helpers import PROVENANCE, SEED, make_fake_run, records

from continuum_sim.cli import main
from continuum_sim.report import detect_kind, write_report
from continuum_sim.report.rerun_export import kerf_columns
from continuum_sim.report.run import parameters_section

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture
def short_run(report_run, tmp_path) -> Path:
    run = tmp_path / "run"
    shutil.copytree(report_run, run)
    return run


@pytest.fixture
def sweep(report_sweep, tmp_path) -> Path:
    copy = tmp_path / "sweep"
    shutil.copytree(report_sweep, copy)
    return copy


def _embedded_images(text: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'<img class="plot"[^>]*src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)]


def test_run_report_holds_outcome_metrics_every_plot_video_overrides_and_config(short_run):
    assert detect_kind(short_run) == "run"
    text = write_report(short_run).read_text()
    metrics = json.loads((short_run / "metrics.json").read_text())
    assert metrics["task"]["failure"] == "partial_run"
    assert 'id="outcome"' in text and "task failed: partial_run" in text
    # every PNG of plots/ embedded byte for byte, nothing fetched from elsewhere
    pngs = sorted((short_run / "plots").glob("*.png"))
    assert len(pngs) >= 6
    assert sorted(_embedded_images(text)) == sorted(p.read_bytes() for p in pngs)
    assert not re.search(r'(src|href)="(https?:)?//', text)
    # key metrics with units, from metrics.json
    table = text[text.index('<table id="metrics">'):]
    table = table[: table.index("</table>")]
    assert "cpu_real_time_factor" in table and "× real time" in table
    gap_mm = 1000 * metrics["min_arm_distance_m"]
    assert f"<td>{gap_mm:.4g}</td><td>mm</td>" in table
    # the video, linked next to the page
    assert re.search(r'<video id="video" controls preload="metadata" poster="poster.png" src="video.mp4">', text)
    # the override against the shipped defaults, and the resolved config itself
    overrides = text[text.index('<table id="overrides">'):]
    assert f'<td class="l">simulation.seed</td><td class="l">{SEED}</td><td class="l">0</td>' in overrides
    assert "[simulation]" in text and "seed = 7" in text


def test_parameters_section_shows_the_registry_when_the_run_has_parameters_json(short_run):
    run = short_run
    written = parameters_section(run)  # every run writes parameters.json: the registry's records at its values
    assert '<table id="parameters"' in written and "model.cable_friction.mu" in written
    registry = {"model.stiffness_scale": {"value": 1.0, "unit": "1", "status": "assumed", "source": "SPEC §1", "range": [0.5, 8]},
                "arm.spool_radius": {"value": 0.01, "unit": "m", "status": "measured", "source": "paper", "range": [0.005, 0.02]}}
    (run / "parameters.json").write_text(json.dumps(registry))
    html = parameters_section(run)
    assert '<table id="parameters"' in html
    for name in ("path", "value", "unit", "status", "source", "range"):
        assert f'<th class="l">{name}</th>' in html
    assert '<td class="l path">arm.spool_radius</td><td class="l">0.01</td><td class="l">m</td><td class="l">measured</td>' in html


def test_sweep_report_compares_the_variants_links_kept_runs_and_embeds_the_plots(sweep):
    assert (sweep / "report.html").is_file()  # written by `sweep` itself
    recs = records(sweep)
    kept = sweep / "runs" / recs[0]["variant_id"]
    kept.mkdir(parents=True)
    (kept / "report.html").write_text("<html></html>")
    assert main(["report", str(sweep)]) == 0
    text = (sweep / "report.html").read_text()
    assert detect_kind(sweep) == "sweep"
    table = text[text.index('<table id="metrics">'): text.index("</table>", text.index('<table id="metrics">'))]
    assert table.count("<tr>") == 1 + len(recs) == 3
    for rec in recs:
        assert f"<td>{rec['metrics']['sag_mm']:.4g}</td>" in table
    assert f'<a href="runs/{recs[0]["variant_id"]}/report.html">' in table
    assert sorted(_embedded_images(text)) == sorted(p.read_bytes() for p in (sweep / "plots").glob("*.png"))
    assert "2 variants recorded: 2 ok, 0 failed" in text


def test_validation_identification_and_generic_study_folders_get_their_pages(tmp_path, capsys):
    validation = tmp_path / "validation"
    shutil.copytree(REPO / "validation" / "report", validation)
    identify = tmp_path / "identify"
    identify.mkdir()
    shutil.copy(REPO / "validation" / "opencr_ftdcr_v4" / "ftdcr_v4_identify_report.json", identify / "report.json")
    shutil.copy(REPO / "validation" / "opencr_ftdcr_v4" / "ftdcr_v4_identified.toml", identify / "identified.toml")
    study = tmp_path / "study"
    (study / "plots").mkdir(parents=True)
    (study / "summary.json").write_text(json.dumps({"best_value": 0.25, "trials": 40, "history": [1, 2]}))
    (study / "indices.csv").write_text("parameter,S1,ST\nmodel.stiffness_scale,0.61,0.7\ncontrol.pretension,0.12,0.2\n")
    shutil.copy(REPO / "docs" / "stiffness_sweep.png", study / "plots" / "indices.png")
    replay = tmp_path / "replay"  # `continuum-sim replay`'s folder has a config and a trajectory, but is no run
    replay.mkdir()
    for name, text in (("config.toml", ""), ("trajectory.npz", ""), ("replay.json", '{"samples": 3}')):
        (replay / name).write_text(text)
    for folder, kind in ((validation, "validation"), (identify, "identification"), (study, "study"), (replay, "study")):
        assert main(["report", str(folder)]) == 0
        assert f"({kind} report," in capsys.readouterr().out
    rows = json.loads((validation / "report.json").read_text())["rows"]
    text = (validation / "report.html").read_text()
    table = text[text.index('<table id="metrics">'): text.index("</table>", text.index('<table id="metrics">'))]
    assert table.count("<tr>") == 1 + len(rows)
    assert len(_embedded_images(text)) == len(list(validation.glob("*.png")))
    fitted = json.loads((identify / "report.json").read_text())["parameters"]
    text = (identify / "report.html").read_text()
    assert all(f'<td class="l">{name}</td>' in text for name in fitted) and "identified.toml" in text
    text = (study / "report.html").read_text()
    assert '<td class="l">model.stiffness_scale</td><td>0.61</td><td>0.7</td>' in text
    assert "<td>0.25</td>" in text and len(_embedded_images(text)) == 1


def test_report_of_a_folder_with_nothing_to_show_is_one_line_exit_2(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "holds no run, sweep" in err
    assert not (tmp_path / "report.html").exists()


def test_run_prints_its_outcome_and_require_completed_exits_1_naming_the_failure(tmp_path, short_run, monkeypatch, capsys):
    import continuum_sim.scenario.runner as runner

    failed = json.loads((short_run / "metrics.json").read_text())  # a real run's metrics: partial_run

    def fake_run(config, out, **kwargs):  # the pipeline is tested elsewhere; here: what `run` makes of a failed task
        shutil.copy(short_run / "metrics.json", out / "metrics.json")
        return failed

    monkeypatch.setattr(runner, "run_scenario", fake_run)
    assert main(["run", "--out", str(tmp_path / "a"), "--quiet"]) == 0  # default unchanged: the run itself finished
    out = capsys.readouterr().out
    assert out.strip().splitlines()[-1] == "outcome: task FAILED: partial_run (metrics.json: task.failure)"
    assert (tmp_path / "a" / "report.html").is_file()
    assert main(["run", "--out", str(tmp_path / "b"), "--quiet", "--require-completed"]) == 1
    captured = capsys.readouterr()
    assert "outcome: task FAILED: partial_run" in captured.out
    assert captured.err.strip() == "continuum-sim run: the task failed: partial_run (--require-completed)"
    completed = dict(failed, task={"completed": True, "failure": None, "cables_saturated": False})
    monkeypatch.setattr(runner, "run_scenario", lambda config, out, **kw: completed)
    assert main(["run", "--out", str(tmp_path / "c"), "--quiet", "--require-completed"]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1] == "outcome: task completed"


def test_kerf_columns_take_the_band_cells_times():
    """A straight kerf along x on a 1 mm grid: band cells (within a quarter kerf width) carry their
    own recorded times, flank columns the nearest band cell's; a count mismatch shows all at the end."""
    nx, ny, width = 40, 20, 0.008
    kerf_map = np.zeros((nx, ny))
    kerf_map[5:35, 6:14] = 1.0  # an 8 mm wide cut, y in [6, 14) mm
    cutting = {"kerf_map": kerf_map, "kerf_map_lo": np.zeros(3), "kerf_map_spacing": np.full(3, 0.001)}
    line = np.array([[0.0, 0.010, 0.0], [0.040, 0.010, 0.0]])
    # band: |y - 10 mm| <= 2 mm -> rows 8..11 (centres 8.5..11.5 mm), all 40 columns, grid (C) order
    band_x = np.repeat(np.arange(nx), 4) * 0.001 + 0.0005
    times = band_x * 100.0  # cut left to right, 0.1 s per mm
    centres, fraction, appear = kerf_columns(cutting, times, line, width)
    assert len(centres) == 30 * 8 and np.all(fraction == 1.0)
    np.testing.assert_allclose(appear, centres[:, 0] * 100.0)  # every column: the time of the band cell at its x
    _, _, late = kerf_columns(cutting, times[:-1], line, width)
    assert np.all(np.isinf(late))


def test_export_rerun_writes_a_loadable_recording(short_run, tmp_path, capsys):
    pytest.importorskip("rerun", reason="rerun-sdk is not installed (the optional extra: pip install -e '.[replay]')")
    from rerun.chunk import RrdReader

    out = tmp_path / "run.rrd"
    assert main(["export", str(short_run), "--rerun", "--out", str(out)]) == 0
    assert "frames" in capsys.readouterr().out
    store = RrdReader(out).store()
    text = str(store.schema())
    for entity in ("/world/left/disks", "/world/right/backbone", "/world/left/tool", "/world/left/planned_path",
                   "/world/right/measured_path", "/world/plate", "/world/sample", "/plots/tool_centre_error_mm/left",
                   "/plots/tension_n/right/cable_2_2"):
        assert entity in text, entity


def test_export_without_rerun_sdk_is_one_line_exit_2_naming_the_extra(short_run, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun -> ImportError
    assert main(["export", str(short_run), "--rerun"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and '.[replay]' in err
    assert main(["export", str(short_run)]) == 2
    assert "--rerun" in capsys.readouterr().err


def test_a_diverged_run_still_gets_its_report_and_outcome_line(tmp_path, short_run, monkeypatch, capsys):
    import continuum_sim.scenario.runner as runner

    def diverging(config, out, **kwargs):  # what run_scenario does on divergence: partial results written, then raise
        shutil.copy(short_run / "metrics.json", out / "metrics.json")
        raise runner.SimulationDiverged("simulation diverged: t = 0.2 s: MuJoCo warning (test)")

    monkeypatch.setattr(runner, "run_scenario", diverging)
    assert main(["run", "--out", str(tmp_path / "d"), "--quiet"]) == 3
    captured = capsys.readouterr()
    assert captured.out.strip().splitlines()[-1] == "outcome: task FAILED: diverged (metrics.json: status_reason)"
    text = (tmp_path / "d" / "report.html").read_text()
    assert "(run diverged (simulation diverged: t = 0.2 s: MuJoCo warning (test)))" in text


def _table(text: str, css_id: str) -> str:
    start = text.index(f'<table id="{css_id}"')
    return text[start: text.index("</table>", start)]


def _commands(text: str) -> list[list[str]]:
    import html
    import shlex

    return [shlex.split(html.unescape(c)) for c in re.findall(r'<code class="cmd">(.*?)</code>', text)]


def _parses(argv: list[str]) -> argparse.Namespace:
    """``argv`` (``continuum-sim ...``) through the real CLI parser, without running anything."""
    from continuum_sim.cli.parser import build_parser

    assert argv[0] == "continuum-sim"
    return build_parser().parse_args(argv[1:])


@pytest.fixture
def fake_run(tmp_path) -> Path:
    return make_fake_run(tmp_path / "fake")


def test_parameters_json_renders_as_one_row_per_registry_parameter_with_overrides_marked(fake_run):
    from continuum_sim.params.registry import REGISTRY

    doc = json.loads((fake_run / "parameters.json").read_text())
    assert set(doc) == {"parameters", "overrides"} and doc["overrides"] == {"model.cable_friction.mu": 0.2}
    text = write_report(fake_run).read_text()
    table = _table(text, "parameters")
    assert table.count("<tr") == 1 + len(REGISTRY) >= 25
    header = re.findall(r'<th class="l">([^<]*)</th>', table[: table.index("</thead>")])
    assert header == ["name", "path", "value", "unit", "status", "source", "range", "override"]
    default = next(e["default"] for e in doc["parameters"] if e["path"] == "model.cable_friction.mu")
    row = next(r for r in table.split("<tr")[1:] if "model.cable_friction.mu<" in r)
    assert row.startswith(' class="ovr">') and f"yes (default {default!r})" in row
    assert sum(1 for r in table.split("<tr")[1:] if r.startswith(' class="ovr"')) == 1
    assert "\\u" not in text and "→" in table  # the registry's own characters, not JSON escapes


def test_the_video_gets_a_poster_frame_two_thirds_in_and_none_without_a_video(fake_run):
    import imageio.v3 as iio

    text = write_report(fake_run).read_text()
    poster = fake_run / "poster.png"
    assert poster.is_file() and '<video id="video" controls preload="metadata" poster="poster.png" src="video.mp4">' in text
    assert abs(float(iio.imread(poster).mean()) - 20 * 7) < 10  # frame 7 of 12 (grey level 20 k)
    assert "poster.png" not in "".join(re.findall(r"<figcaption>(.*?)</figcaption>", text))  # not a plot
    poster.unlink()
    (fake_run / "video.mp4").unlink()
    text = write_report(fake_run).read_text()
    assert not poster.exists() and "poster=" not in text and "No video" in text


def test_provenance_section_shows_the_commit_or_says_it_is_missing(fake_run, tmp_path):
    text = write_report(fake_run).read_text()
    assert 'id="provenance-section"' in text and "No provenance.json in this folder" in text
    (fake_run / "provenance.json").write_text(json.dumps(PROVENANCE))
    table = _table(write_report(fake_run).read_text(), "provenance")
    assert "0123456789ab (dirty); changed: continuum_sim/report/run.py" in table
    assert "c0dec0dec0de" in table and "aaaaaaaaaaaa" in table and "mujoco 3.17.0" in table and "(2 cores)" in table
    study = tmp_path / "sens"
    shutil.copytree(REPO / "docs" / "sensitivity" / "quick_open", study)
    (study / "provenance.json").write_text(json.dumps(PROVENANCE))
    assert "0123456789ab (dirty)" in _table(write_report(study).read_text(), "provenance")


@pytest.mark.parametrize("name, method, columns", [
    ("quick_open", "Morris", ("μ*", "μ* 95 % ± (mu_star_conf)", "σ", "μ")),
    ("sobol_open", "Sobol&#x27;", ("S_T", "S_T 95 % ± (ST_conf)", "S1", "S1 95 % ± (S1_conf)")),
])
def test_a_sensitivity_folder_gets_its_indices_with_intervals_and_a_rerun_that_parses(tmp_path, name, method, columns):
    folder = tmp_path / name
    shutil.copytree(REPO / "docs" / "sensitivity" / name, folder)
    (folder / "sweep.json").write_text("{}")  # the sample store's marker, which a real study folder holds too
    (folder / "spec.toml").write_text("# the spec as given\n")
    assert detect_kind(folder) == "sensitivity"
    text = write_report(folder).read_text()
    assert f"<title>Sensitivity study ({method}) {name}</title>" in text and "results.csv" not in text
    summary = json.loads((folder / "summary.json").read_text())
    first = _table(text, "indices-0")
    header = re.findall(r"<th[^>]*>([^<]*)</th>", first)
    assert header == ["parameter", *columns]
    assert first.count("<tr>") == 1 + len(summary["parameters"])
    assert text.count('class="indices"') == len(summary["metrics"])
    assert len(_embedded_images(text)) == 2
    rerun, report = _commands(text)
    args = _parses(rerun)
    assert args.func.__name__ == "cmd_sensitivity" and args.spec == str(folder / "spec.toml") and args.out == str(folder)
    assert _parses(report).func.__name__ == "cmd_report"


def test_an_optimize_folder_gets_its_pareto_front_objectives_first_and_a_rerun_that_parses(tmp_path):
    folder = tmp_path / "task_tpe"
    shutil.copytree(REPO / "docs" / "optimize" / "task_tpe", folder)
    assert detect_kind(folder) == "optimize"
    text = write_report(folder).read_text()
    assert "<title>Design optimisation (TPE) task_tpe</title>" in text
    summary = json.loads((folder / "summary.json").read_text())
    objectives = [o["label"] for o in summary["objectives"]]
    with (folder / "pareto.csv").open() as f:
        front = list(csv.DictReader(f))
    for css_id, n_rows in (("pareto", len(front)), ("best", len(summary["best"]))):
        table = _table(text, css_id)
        titles = re.findall(r'<th class="[^"]*" title="([^"]*)"', table)
        assert titles[: 1 + len(objectives)] == ["trial", *objectives]
        assert table.count('class="obj"') == len(objectives) and table.count("<tr>") == 1 + n_rows
    first = summary["best"][0]
    assert f'<a href="{first["config"]}">{first["trial"]}</a>' in _table(text, "pareto")
    assert len(_embedded_images(text)) == 2
    rerun, report = _commands(text)
    args = _parses(rerun)
    assert args.func.__name__ == "cmd_optimize" and args.spec == str(folder / "evaluations" / "spec.toml") and args.out == str(folder)
    assert _parses(report).func.__name__ == "cmd_report"
