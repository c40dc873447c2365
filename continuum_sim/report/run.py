"""The page of one run folder (``continuum-sim run``): outcome, key metrics, plots, video, parameters, config."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

from . import html as h
from .html import read_json
from .provenance import folder_page

DEFAULTS_TOML = Path(__file__).resolve().parent.parent / "data" / "scenario.toml"  # the shipped defaults
PLOT_ORDER = ("toolpath.png", "tip_error.png", "cut_kerf.png", "cut_force.png", "section_angles.png", "cable_tensions.png")
VIDEO_NAMES = ("video.mp4", "video.diverged.mp4", "video.failed.mp4", "video.interrupted.mp4")


def _get(metrics: dict[str, Any], dotted: str) -> Any:
    value: Any = metrics
    for key in dotted.split("."):
        if not isinstance(value, dict) or key not in value:
            return None
        value = value[key]
    return value


# (label, dotted key in metrics.json, unit, scale): the headline figures of a run.
KEY_METRICS: tuple[tuple[str, str, str, float], ...] = (
    ("cutting error, mean", "cutting_tip_error_mm.mean", "mm", 1.0),
    ("cutting error, RMS", "cutting_tip_error_mm.rms", "mm", 1.0),
    ("cutting error, max", "cutting_tip_error_mm.max", "mm", 1.0),
    ("cut-path deviation, mean", "cut_path_deviation_mm.mean", "mm", 1.0),
    ("cut-path deviation, max", "cut_path_deviation_mm.max", "mm", 1.0),
    ("spindle-axis error, max", "spindle_axis_error_deg.max", "°", 1.0),
    ("kerf coverage", "cutting.kerf.coverage", "fraction", 1.0),
    ("removed foam volume", "cutting.removed_volume_m3", "cm³", 1e6),
    ("cutting force, max", "cutting.force_n.max", "N", 1.0),
    ("spindle stalls", "cutting.stall_events", "count", 1.0),
    ("sample cut free at", "detach_time_s", "s", 1.0),
    ("sample held at end", "sample_held_at_end", "", 1.0),
    ("detached before the cut was complete", "detached_before_cut_complete", "", 1.0),
    ("smallest gap between the arms", "min_arm_distance_m", "mm", 1000.0),
    ("arms touched", "arms_touched", "", 1.0),
    ("cable tension, max", "max_cable_tension_n", "N", 1.0),
    ("cable tension, min", "min_cable_tension_n", "N", 1.0),
    ("gripper contact force, max", "max_contact_force_n.gripper", "N", 1.0),
    ("simulated time", "sim_seconds", "s", 1.0),
    ("time step", "timestep_s", "ms", 1000.0),
    ("wall time (video included)", "wall_seconds", "s", 1.0),
    ("CPU time (this process)", "cpu_seconds", "s", 1.0),
    ("CPU real-time factor", "cpu_real_time_factor", "× real time", 1.0),
    ("wall real-time factor", "wall_real_time_factor", "× real time", 1.0),
)


def outcome(metrics: dict[str, Any]) -> tuple[bool, str]:
    """(task completed, the outcome line) of a run's metrics."""
    if not metrics:
        return False, "no metrics.json: the run did not finish (see the folder's RUNNING marker or status)"
    task = metrics.get("task") or {}
    status = metrics.get("status", "complete")
    reason = f" ({metrics['status_reason']})" if metrics.get("status_reason") else ""
    if task.get("completed"):
        return status == "complete", f"task completed (run {status}{reason})"
    return False, f"task failed: {task.get('failure') or 'unknown'} (run {status}{reason})"


def key_metrics_table(metrics: dict[str, Any]) -> str:
    rows = []
    for label, key, unit, scale in KEY_METRICS:
        value = _get(metrics, key)
        if value is None and key not in ("detach_time_s",):
            continue
        if isinstance(value, (int, float)) and not isinstance(value, bool) and scale != 1.0:
            value = value * scale
        rows.append((label, value, unit, key))
    return h.table(("metric", "value", "unit", "metrics.json key"), rows, css_id="metrics")


def tip_error_table(metrics: dict[str, Any]) -> str:
    """Tool-centre error per arm and stage (mean / max, mm)."""
    per_arm = metrics.get("tip_error_mm") or {}
    stages: list[str] = [s for s in metrics.get("stages_run") or [] if any(s in stats for stats in per_arm.values())]
    for stats in per_arm.values():
        stages += [s for s in stats if s not in stages]  # "all" (and any stage the run did not list) last
    if not stages:
        return ""
    rows = []
    for arm, stats in per_arm.items():
        cells = [f"{h.number((stats.get(s) or {}).get('mean'), 3)} / {h.number((stats.get(s) or {}).get('max'), 3)}" for s in stages]
        rows.append((arm, *cells))
    return "<p>Tool-centre error against the plan, mean / max in mm, per stage:</p>" + h.table(("arm", *stages), rows)


def flatten(data: Any, prefix: str = "") -> dict[str, Any]:
    """Nested TOML/JSON tables as dotted paths → leaf values (lists are leaves)."""
    out: dict[str, Any] = {}
    for key, value in data.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, path + "."))
        else:
            out[path] = value
    return out


def overrides(config_path: Path, defaults_path: Path = DEFAULTS_TOML) -> list[tuple[str, Any, Any]]:
    """(path, this run's value, the shipped default) of every field that differs from the defaults."""
    try:
        mine = flatten(tomllib.loads(config_path.read_text()))
        base = flatten(tomllib.loads(defaults_path.read_text()))
    except (OSError, tomllib.TOMLDecodeError):
        return []
    return [(k, mine.get(k), base.get(k)) for k in sorted(set(mine) | set(base)) if mine.get(k) != base.get(k)]


PARAMETER_COLUMNS = ("name", "path", "value", "unit", "status", "source", "range", "override")


def parameter_entries(data: Any) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """(one dict per parameter, the overrides ``{path: value}``) of a ``parameters.json`` document.

    Three shapes are read: the registry's ``{"parameters": [{path, name, value, default, unit,
    status, source, range, log, overridden}, ...], "overrides": {path: value}}``, a bare list of
    such objects, and an older ``{path: {value, unit, ...}}`` mapping.
    """
    if isinstance(data, dict) and isinstance(data.get("parameters"), list):
        entries = [e for e in data["parameters"] if isinstance(e, dict)]
        given = data.get("overrides")
        return entries, dict(given) if isinstance(given, dict) else {}
    if isinstance(data, list):
        return [e for e in data if isinstance(e, dict)], {}
    if isinstance(data, dict):
        return [{"path": k, **(v if isinstance(v, dict) else {"value": v})} for k, v in data.items()], {}
    return [], {}


def _range_text(entry: dict[str, Any]) -> str:
    bounds = entry.get("range")
    if not isinstance(bounds, (list, tuple)) or len(bounds) != 2:
        return "" if bounds is None else _cell(bounds)
    return f"{h.number(bounds[0])} … {h.number(bounds[1])}" + (" (log)" if entry.get("log") else "")


def parameters_table(entries: list[dict[str, Any]], overrides_: dict[str, Any]) -> str:
    """The registry's parameters as a table, one row each: the columns of ``PARAMETER_COLUMNS`` that any row has.

    A row whose path the run overrode (listed in ``overrides_``, or marked ``overridden``) is
    highlighted and its override cell shows the shipped default beside it.
    """
    overridden = {e.get("path") for e in entries if e.get("overridden")} | set(overrides_)
    present = {k for e in entries for k in e} | ({"override"} if overridden or any("default" in e for e in entries) else set())
    columns = [c for c in PARAMETER_COLUMNS if c in present]
    head = "".join(f'<th class="l">{h.esc(c)}</th>' for c in columns)
    body = []
    for e in entries:
        changed = e.get("path") in overridden
        cells = []
        for c in columns:
            if c == "override":
                text = f"yes (default {_cell(e.get('default'))})" if changed and "default" in e else ("yes" if changed else "")
                cells.append(f'<td class="l">{h.esc(text)}</td>')
            elif c == "range":
                cells.append(f'<td class="l rng">{h.esc(_range_text(e))}</td>')
            else:
                cls = {"source": "l src", "path": "l path"}.get(c, "l")
                cells.append(f'<td class="{cls}">{h.esc(_cell(e.get(c), absent=""))}</td>')
        row_class = ' class="ovr"' if changed else ""
        body.append(f"<tr{row_class}>" + "".join(cells) + "</tr>")
    return (f'<div class="wide"><table id="parameters" class="params"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table></div>")


def parameters_section(run_dir: Path) -> str:
    """Parameter values of the run: the registry's table when the folder has ``parameters.json``, then the overrides.

    ``parameters.json`` is written by every run (``scenario.runner.write_parameters``): each
    registry parameter's value, unit, status and source, and the ones this run overrode. Below
    it, the fields of ``config.toml`` that differ from the shipped defaults (registry or not).
    """
    run_dir = Path(run_dir)
    parts = []
    registry = run_dir / "parameters.json"
    if registry.is_file():
        try:
            data = json.loads(registry.read_text())
        except (OSError, ValueError) as exc:
            data = None
            parts.append(f"<p class=\"bad\">parameters.json is unreadable ({h.esc(exc)})</p>")
        entries, given = parameter_entries(data)
        if entries:
            n_over = sum(1 for e in entries if e.get("overridden") or e.get("path") in given)
            parts.append(f"<p>The parameter registry at this run's values (<code>parameters.json</code>): {len(entries)} "
                         f"parameters, {n_over} overridden (highlighted).</p>" + parameters_table(entries, given))
    diff = overrides(run_dir / "config.toml")
    if diff:
        parts.append("<p>Fields that differ from the shipped defaults (<code>continuum_sim/data/scenario.toml</code>):</p>"
                     + h.table(("parameter", "this run", "default"), [(k, _cell(a), _cell(b)) for k, a, b in diff],
                               left=3, css_id="overrides"))
    elif (run_dir / "config.toml").is_file():
        parts.append("<p>Every field has its shipped default value (<code>continuum_sim/data/scenario.toml</code>).</p>")
    return "".join(parts)


def _cell(value: Any, absent: str = "(absent)") -> str:
    """A parameter value as text: floats exactly (repr), lists and objects as JSON with their own characters."""
    if value is None:
        return absent
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, dict)):
        return json.dumps(value, ensure_ascii=False)
    return str(value)


POSTER_NAME = "poster.png"
POSTER_AT = 2 / 3  # the poster frame, as a fraction of the video: well into the cut for the default task


def find_video(run_dir: Path) -> Path | None:
    """The run's video (complete or partial), if any."""
    for name in VIDEO_NAMES:
        if (Path(run_dir) / name).is_file():
            return Path(run_dir) / name
    return None


def write_poster(run_dir: Path) -> Path | None:
    """``poster.png``: the video's frame at ``POSTER_AT`` of its length, shown before the video plays.

    Kept when it is newer than the video; None (and no poster) when the run has no video or
    its frames cannot be read.
    """
    import imageio.v2 as imageio

    from ..configio import atomic_write_bytes

    video = find_video(run_dir)
    poster = Path(run_dir) / POSTER_NAME
    if video is None:
        return None
    if poster.is_file() and poster.stat().st_mtime >= video.stat().st_mtime:
        return poster
    frame = None
    try:
        opened: Any = imageio.get_reader(video, "ffmpeg")  # the ffmpeg plugin's reader (typed as the base class)
        with opened as reader:
            meta = reader.get_meta_data()
            n = int(round(float(meta.get("fps") or 0) * float(meta.get("duration") or 0)))
            index = max(0, int(POSTER_AT * n) - 1)
            try:
                frame = reader.get_data(index)
            except (IndexError, RuntimeError, OSError, ValueError):  # the length was overestimated: the last frame read
                for last in reader:
                    frame = last
    except (OSError, RuntimeError, ValueError, IndexError, StopIteration):
        return None
    if frame is None:
        return None
    import imageio.v3 as iio

    atomic_write_bytes(poster, iio.imwrite("<bytes>", frame, extension=".png"))
    return poster


def video_section(run_dir: Path) -> str:
    """A ``<video>`` element linking the run's MP4 next to the page (not embedded: see docs/report.md)."""
    path = find_video(run_dir)
    if path is not None:
        name = path.name
        size = path.stat().st_size / 1e6
        note = "" if name == "video.mp4" else " (partial: the run did not complete)"
        poster = f' poster="{POSTER_NAME}"' if (run_dir / POSTER_NAME).is_file() else ""
        return (f'<video id="video" controls preload="metadata"{poster} src="{h.esc(name)}"></video>'
                f'<p class="muted">{h.esc(name)}{h.esc(note)}, {size:.1f} MB, next to this page '
                "(overview and cut close-up side by side).</p>")
    return '<p class="muted">No video: run with <code>--video</code> to render one.</p>'


def run_page(run_dir: Path) -> str:
    """The report of a run folder as one HTML document."""
    run_dir = Path(run_dir)
    metrics = read_json(run_dir / "metrics.json")
    ok, line = outcome(metrics)
    sections = [h.banner(ok, line)]
    if metrics:
        sections.append(h.section("Key metrics", key_metrics_table(metrics) + tip_error_table(metrics), "key-metrics"))
    order = {name: k for k, name in enumerate(PLOT_ORDER)}
    plots = sorted((p for p in h.plot_files(run_dir) if p.name != POSTER_NAME), key=lambda p: (order.get(p.name, len(order)), str(p)))
    sections.append(h.section("Plots", h.images(plots, run_dir) if plots else '<p class="muted">No plots.</p>', "plots"))
    sections.append(h.section("Video", video_section(run_dir), "video-section"))
    sections.append(h.section("Parameters", parameters_section(run_dir) or '<p class="muted">No config.toml.</p>', "parameters-section"))
    config = run_dir / "config.toml"
    if config.is_file():
        sections.append(h.section("Configuration", h.preformatted(config.read_text(), "config.toml (the resolved configuration: "
                                                                   "rerun with continuum-sim run --config config.toml)"), "config"))
    if metrics:
        sections.append(h.section("All metrics", h.json_block(metrics, "metrics.json"), "all-metrics"))
    control = metrics.get("control", "?")
    return folder_page(run_dir, f"Run {run_dir.resolve().name}", f"continuum-sim run folder {run_dir} · control: {control}", sections)
