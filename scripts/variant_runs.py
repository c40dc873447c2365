"""Run named variants of the default task (dotted config overrides) and tabulate their outcome.

Shared by scripts/attribution_open_loop.py and scripts/calibrate_open_loop.py: each variant is
the shipped scenario with a few fields replaced (`configio.replace_path`, the same validation as
a TOML), run through `run_scenario` in its own process (`--workers`, default 2), its key
metrics kept. Output: a JSON list (name, overrides, metrics) and a markdown table.
"""

from __future__ import annotations

import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

Overrides = dict[str, Any]


def key_metrics(m: dict[str, Any]) -> dict[str, Any]:
    """The figures the calibration docs quote, from one run's metrics."""
    gripper = [a for a in m["tip_error_mm"] if a != "left"][0] if "right" not in m["tip_error_mm"] else "right"
    clamp = m["tip_error_mm"][gripper].get("clamping", {})
    return {
        "completed": m["task"]["completed"],
        "failure": m["task"]["failure"],
        "path_deviation_mean_mm": m["cut_path_deviation_mm"]["mean"],
        "path_deviation_max_mm": m["cut_path_deviation_mm"]["max"],
        "cutting_error_mean_mm": m["cutting_tip_error_mm"]["mean"],
        "clamping_error_mean_mm": clamp.get("mean"),
        "clamping_error_max_mm": clamp.get("max"),
        "sample_detached": m["sample_detached"],
        "sample_held_at_end": m["sample_held_at_end"],
        "cells_remaining": m["cells_remaining"],
        "max_cable_tension_n": m["max_cable_tension_n"],
        "max_gripper_contact_n": m["max_contact_force_n"].get("gripper"),
    }


def _run_one(name: str, overrides: Overrides, keep: str | None) -> tuple[str, dict[str, Any]]:
    from continuum_sim.configio import replace_path
    from continuum_sim.scenario.config import ScenarioConfig
    from continuum_sim.scenario.runner import run_scenario

    config = ScenarioConfig.default()
    for path, value in overrides.items():
        config = replace_path(config, path, value)
    out = None if keep is None else Path(keep) / name
    try:
        metrics = run_scenario(config, out)
    except Exception as exc:  # a divergent or unplannable variant is a result, not a crash
        return name, {"completed": False, "failure": f"error: {type(exc).__name__}: {exc}"}
    return name, key_metrics(metrics)


def run_variants(variants: list[tuple[str, Overrides]], out_json: Path, workers: int = 2,
                 keep: str | None = None) -> list[dict[str, Any]]:
    """Run every variant not already in ``out_json`` (resumable), return all rows in order."""
    done: dict[str, dict[str, Any]] = {}
    if out_json.exists():
        done = {r["name"]: r for r in json.loads(out_json.read_text()) if r.get("metrics")}
    todo = [(n, o) for n, o in variants if n not in done or done[n]["overrides"] != o]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futs = {pool.submit(_run_one, n, o, keep): (n, o) for n, o in todo}
        for k, fut in enumerate(as_completed(futs), 1):
            n, o = futs[fut]
            _, metrics = fut.result()
            done[n] = {"name": n, "overrides": o, "metrics": metrics}
            print(f"[{k}/{len(todo)}] {n}: {_short(metrics)}", file=sys.stderr, flush=True)
            rows = [done[v] for v, _ in variants if v in done]
            tmp = out_json.with_suffix(".tmp")
            tmp.write_text(json.dumps(rows, indent=1))
            tmp.replace(out_json)
    return [done[n] for n, _ in variants]


def _fmt(v: Any, digits: int = 2) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def _short(m: dict[str, Any]) -> str:
    return (f"{'completed' if m.get('completed') else m.get('failure')}, path dev "
            f"{_fmt(m.get('path_deviation_mean_mm'))} mm, clamping {_fmt(m.get('clamping_error_mean_mm'))} mm")


def markdown_table(rows: list[dict[str, Any]]) -> str:
    head = ("| variant | overrides | outcome | path deviation mean / max (mm) | cutting error mean (mm) | "
            "clamping-stage gripper error mean / max (mm) | sample held at end | peak cable tension (N) |")
    lines = [head, "|" + "---|" * 8]
    for r in rows:
        m = r["metrics"]
        ov = ", ".join(f"`{k}={v}`" for k, v in r["overrides"].items()) or "(none)"
        outcome = "completed" if m.get("completed") else f"`{m.get('failure')}`"
        lines.append(
            f"| {r['name']} | {ov} | {outcome} | {_fmt(m.get('path_deviation_mean_mm'))} / "
            f"{_fmt(m.get('path_deviation_max_mm'))} | {_fmt(m.get('cutting_error_mean_mm'))} | "
            f"{_fmt(m.get('clamping_error_mean_mm'))} / {_fmt(m.get('clamping_error_max_mm'))} | "
            f"{_fmt(m.get('sample_held_at_end'))} | {_fmt(m.get('max_cable_tension_n'), 0)} |")
    return "\n".join(lines) + "\n"
