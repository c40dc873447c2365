"""The pages of study folders: a sweep, a validation report, an identification, and any later study.

Each reads only the files its command wrote (see ``pages.detect_kind`` for how a folder is
recognised) and shows them as tables and embedded plots; links to variant runs are
relative, so the folder can be moved or archived whole.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from . import html as h
from .html import read_json
from .provenance import folder_page

MAX_TABLE_ROWS = 500  # rows of a CSV summary shown on the page (the file holds them all)


def _csv_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    try:
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = next(reader, [])
            return header, list(reader)
    except (OSError, csv.Error):
        return [], []


def _numeric(text: str) -> Any:
    try:
        return float(text) if text not in ("", "None") else None
    except ValueError:
        return text


def _csv_table(path: Path, css_id: str, link: dict[str, str] | None = None, skip: tuple[str, ...] = ()) -> str:
    """A CSV file as a table (numbers to 4 significant figures); ``link`` maps a row's id to an href."""
    header, rows = _csv_rows(path)
    if not header:
        return f'<p class="muted">{h.esc(path.name)} is missing or empty.</p>'
    keep = [i for i, c in enumerate(header) if c not in skip]
    cells = []
    for row in rows[:MAX_TABLE_ROWS]:
        out: list[Any] = []
        for i in keep:
            value = row[i] if i < len(row) else ""
            if link is not None and header[i] == "variant_id" and value in link:
                out.append(f'<a href="{h.esc(link[value])}">{h.esc(value)}</a>')
            else:
                out.append(h.esc(h.number(_numeric(value))))
        cells.append(out)
    more = f'<p class="muted">{len(rows) - MAX_TABLE_ROWS} more rows in {h.esc(path.name)}.</p>' if len(rows) > MAX_TABLE_ROWS else ""
    left = sum(1 for i in keep if header[i] in ("variant_id", "status", "error", "check", "name", "reference", "quantity"))
    return h.table([header[i] for i in keep], cells, left=max(left, 1), css_id=css_id, raw=True) + more


def sweep_page(root: Path) -> str:
    """A sweep's results folder: the swept grid, the comparison table (links to kept variant runs), every plot."""
    root = Path(root)
    marker = read_json(root / "sweep.json")
    identity = marker.get("identity") or {}
    records = [read_json(p) for p in sorted((root / "records").glob("*.json"))]
    n_ok = sum(1 for r in records if r.get("status") == "ok")
    failed = [r for r in records if r.get("status") != "ok"]
    ok = not failed and bool(records)
    line = f"{len(records)} variants recorded: {n_ok} ok, {len(failed)} failed" if records else "no variant recorded yet"
    sections = [h.banner(ok, line)]
    grid = identity.get("grid") or {}
    evaluation = identity.get("evaluation") or {}
    if grid:
        rows = [(path, ", ".join(h.number(v) for v in values) if isinstance(values, list) else values) for path, values in grid.items()]
        sections.append(h.section("Grid", h.table(("parameter", "values"), rows, left=2)
                                  + f"<p>Evaluation: <code>{h.esc(json.dumps(evaluation, sort_keys=True))}</code></p>", "grid"))
    links = {}
    for run in sorted((root / "runs").glob("*")) if (root / "runs").is_dir() else []:
        target = run / "report.html"
        links[run.name] = f"runs/{run.name}/report.html" if target.is_file() else f"runs/{run.name}/"
    note = "<p>Each row links to its variant's run folder (kept with <code>keep_runs = true</code>).</p>" if links else ""
    sections.append(h.section("Comparison", note + _csv_table(root / "results.csv", "metrics", links), "comparison"))
    if failed:
        sections.append(h.section("Failed variants", h.table(("index", "variant", "error"),
                                                              [(r.get("index"), r.get("variant_id"), r.get("error")) for r in failed],
                                                              left=3), "failed"))
    plots = sorted(h.plot_files(root), key=lambda p: (not p.name.startswith("overview"), "heatmap" not in p.name, str(p)))
    sections.append(h.section("Plots", h.images(plots, root) if plots else '<p class="muted">No plots.</p>', "plots"))
    spec = root / "spec.toml"
    if spec.is_file():
        sections.append(h.section("Spec", "<p>Rerun (resumes: variants already recorded are skipped):</p>"
                                  + h.command(["continuum-sim", "sweep", str(spec), "--out", str(root)])
                                  + h.preformatted(spec.read_text(), "spec.toml"), "config"))
    return folder_page(root, f"Sweep {root.resolve().name}", f"continuum-sim sweep results folder {root}", sections)


def validation_page(root: Path) -> str:
    """``continuum-sim validate``'s folder: every check's rows with its verdict, and the comparison plots."""
    root = Path(root)
    report = read_json(root / "report.json")
    rows = report.get("rows") or []
    failed = [r for r in rows if not r.get("passed", True)]
    line = (f"{len(rows)} comparisons: {len(rows) - len(failed)} within their limits, {len(failed)} outside"
            + (" (quick mode)" if report.get("quick") else ""))
    sections = [h.banner(bool(rows) and not failed, line)]
    if rows:
        columns = [c for c in ("check", "reference", "quantity", "measured", "tolerance", "passed") if any(c in r for r in rows)]
        sections.append(h.section("Checks", h.table(columns, [[r.get(c) for c in columns] for r in rows], left=3, css_id="metrics"),
                                  "checks"))
    plots = h.plot_files(root)
    sections.append(h.section("Plots", h.images(plots, root) if plots else '<p class="muted">No plots.</p>', "plots"))
    if (root / "report.md").is_file():
        sections.append(h.section("report.md", h.preformatted((root / "report.md").read_text(), "report.md"), "config"))
    return folder_page(root, f"Validation {root.resolve().name}", f"continuum-sim validate report folder {root}", sections)


def identify_page(root: Path) -> str:
    """``continuum-sim identify``'s folder: fitted values with standard errors, RMSE before/after, plots, identified.toml."""
    root = Path(root)
    report = read_json(root / "report.json")
    before, after = report.get("rmse_before_mm"), report.get("rmse_after_mm")
    unidentifiable = report.get("unidentifiable") or []
    ok = bool(report) and not unidentifiable
    line = f"position RMSE {h.number(before)} → {h.number(after)} mm" + (
        f"; unidentifiable: {', '.join(map(str, unidentifiable))}" if unidentifiable else "")
    sections = [h.banner(ok, line)]
    details = report.get("details") or {}
    params = report.get("parameters") or {}
    rows = []
    for path, value in params.items():
        d = details.get(path) or {}
        ci = d.get("ci95") or [None, None]
        bounds = d.get("bounds") or [None, None]
        verdict = "yes" if d.get("identifiable", True) else f"no: {d.get('why_not', '')}"
        rows.append((path, value, d.get("std_error"), f"{h.number(ci[0])} … {h.number(ci[1])}", d.get("initial"),
                     f"{h.number(bounds[0])} … {h.number(bounds[1])}", verdict))
    if rows:
        sections.append(h.section("Fitted parameters", h.table(("parameter", "fitted", "std error", "95 % interval", "initial", "bounds",
                                                                "identifiable"), rows, css_id="metrics"), "fit"))
    summary = [(k, report.get(k)) for k in ("rmse_before_mm", "rmse_after_mm", "nfev", "replays", "cpu_s", "status") if k in report]
    if summary:
        sections.append(h.section("Fit", h.table(("quantity", "value"), summary), "fit-summary"))
    plots = h.plot_files(root)
    sections.append(h.section("Plots", h.images(plots, root) if plots else '<p class="muted">No plots.</p>', "plots"))
    if (root / "identified.toml").is_file():
        sections.append(h.section("identified.toml", h.preformatted((root / "identified.toml").read_text(),
                                                                    "identified.toml (use with --config)"), "config"))
    sections.append(h.section("report.json", h.json_block(report, "report.json"), "all-metrics"))
    return folder_page(root, f"Identification {root.resolve().name}", f"continuum-sim identify folder {root}", sections)


def generic_page(root: Path) -> str:
    """Any other study folder (sensitivity, optimisation, ...): its JSON and CSV summaries as tables, its PNGs.

    A JSON object's scalar entries become a table and its nested parts a collapsible block;
    each CSV becomes a table. Nothing here knows the study: a new kind gets a page at once,
    and a dedicated one when it needs more.
    """
    root = Path(root)
    sections = []
    for path in sorted(root.glob("*.json")):
        data = read_json(path)
        scalars = [(k, v) for k, v in data.items() if not isinstance(v, (dict, list))]
        body = h.table(("key", "value"), scalars) if scalars else ""
        nested = {k: v for k, v in data.items() if isinstance(v, (dict, list))}
        if nested:
            body += h.json_block(nested, f"{path.name}: nested entries")
        sections.append(h.section(path.name, body or '<p class="muted">(not a JSON object)</p>'))
    for i, path in enumerate(sorted(root.glob("*.csv"))):
        sections.append(h.section(path.name, _csv_table(path, "metrics" if i == 0 else f"table-{i}")))
    plots = h.plot_files(root)
    sections.append(h.section("Plots", h.images(plots, root) if plots else '<p class="muted">No plots.</p>', "plots"))
    for path in sorted(root.glob("*.toml")):
        sections.append(h.section(path.name, h.preformatted(path.read_text(), path.name), "config"))
    n_plots = len(plots)
    banner = h.banner(True, f"study folder: {len(list(root.glob('*.json')))} JSON and {len(list(root.glob('*.csv')))} CSV summaries, "
                            f"{n_plots} plots")
    return folder_page(root, f"Study {root.resolve().name}", f"folder {root}", [banner, *sections])
