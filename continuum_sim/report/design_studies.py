"""The pages of a sensitivity study (``continuum-sim sensitivity``) and a design optimisation (``continuum-sim optimize``).

Both read only the files their command wrote: ``summary.json`` (method or sampler, the
parameters or variables, the analysis or the best designs), the CSV tables and the plots.
Each page ends with the command that resumes or reruns the study.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from . import html as h
from .html import read_json
from .provenance import folder_page
from .studies import MAX_TABLE_ROWS, _csv_rows, _csv_table, _numeric

METHODS = {"morris": "Morris", "sobol": "Sobol'"}
# Index columns per method, as analysed (indices.csv's columns): key, header; the first is the ranking.
INDEX_COLUMNS = {
    "morris": (("mu_star", "μ*"), ("mu_star_conf", "μ* 95 % ± (mu_star_conf)"), ("sigma", "σ"), ("mu", "μ")),
    "sobol": (("ST", "S_T"), ("ST_conf", "S_T 95 % ± (ST_conf)"), ("S1", "S1"), ("S1_conf", "S1 95 % ± (S1_conf)")),
}
SAMPLERS = {"nsga2": "NSGA-II", "tpe": "TPE", "cmaes": "CMA-ES", "random": "random", "grid": "grid"}


def study_kind(folder: Path) -> str | None:
    """``sensitivity`` or ``optimize`` when ``folder/summary.json`` is one of theirs, else None."""
    summary = read_json(Path(folder) / "summary.json")
    if summary.get("kind") == "sensitivity" or (summary.get("method") in METHODS and "analysis" in summary):
        return "sensitivity"
    if summary.get("kind") == "optimize" or ("objectives" in summary and "sampler" in summary):
        return "optimize"
    return None


def _spec_copy(root: Path, *candidates: str) -> str:
    """The study's own copy of its spec (the store keeps the spec as given), else the placeholder SPEC.toml."""
    for name in candidates:
        if (root / name).is_file():
            return str(root / name)
    return "SPEC.toml"


def _rerun(root: Path, command: str, spec: str, what: str) -> str:
    note = ("" if spec != "SPEC.toml" else
            " (SPEC.toml: the spec the study was run with; this folder holds no copy of it)")
    return (f"<p>Resume or extend it with the same spec ({what} already recorded are reused){h.esc(note)}, "
            "then rewrite this page:</p>"
            + h.command(["continuum-sim", command, spec, "--out", str(root)])
            + h.command(["continuum-sim", "report", str(root)]))


def _plots(root: Path) -> str:
    plots = h.plot_files(root)
    return h.section("Plots", h.images(plots, root) if plots else '<p class="muted">No plots.</p>', "plots")


def sensitivity_page(root: Path) -> str:
    """A sensitivity study: its outcome, the parameters ranked, the indices per metric with their 95 % intervals, plots."""
    root = Path(root)
    summary = read_json(root / "summary.json")
    method = str(summary.get("method", "morris"))
    label = METHODS.get(method, method)
    rows, recorded, failed = summary.get("rows"), summary.get("rows_recorded"), summary.get("failed") or 0
    line = (f"{label}, {summary.get('control_mode', '?')} loop, evaluation {(summary.get('evaluation') or {}).get('kind', '?')}: "
            f"{recorded}/{rows} samples recorded, {failed} failed")
    if summary.get("completed_fraction") is not None:
        line += f"; task completed in {100 * summary['completed_fraction']:.0f} % of the samples"
    if summary.get("cpu_s_total") is not None:
        line += f"; {summary['cpu_s_total']:.0f} s CPU"
    sections = [h.banner(bool(summary) and not failed and recorded == rows, line)]
    strength = summary.get("strength") or {}
    params = sorted(summary.get("parameters") or [], key=lambda p: -(strength.get(p.get("path"), 0.0) or 0.0))
    if params:
        table = h.table(("parameter", "low", "high", "log", "strength"),
                        [(p.get("path"), *(p.get("range") or [None, None]), bool(p.get("log")), strength.get(p.get("path")))
                         for p in params], css_id="factors")
        sections.append(h.section("Parameters", "<p>Strongest first (strength: the largest index over the metrics, "
                                                "relative to the strongest parameter).</p>" + table, "factors-section"))
    sections.append(h.section("Indices", _indices(root, summary, method), "indices"))
    sections.append(_plots(root))
    if (root / "summary.md").is_file():
        sections.append(h.section("summary.md", h.preformatted((root / "summary.md").read_text(), "summary.md"), "summary-md"))
    if (root / "samples.csv").is_file():
        sections.append(h.section("Samples", f"<details><summary>samples.csv (first {MAX_TABLE_ROWS} rows)</summary>"
                                  + _csv_table(root / "samples.csv", "samples", skip=("variant_id",)) + "</details>", "samples"))
    spec = _spec_copy(root, "spec.toml")
    body = _rerun(root, "sensitivity", spec, "samples")
    if spec != "SPEC.toml":
        body += h.preformatted(Path(spec).read_text(), "spec.toml")
    sections.append(h.section("Rerun", body, "rerun"))
    return folder_page(root, f"Sensitivity study ({label}) {root.resolve().name}", f"continuum-sim sensitivity folder {root}", sections)


def _indices(root: Path, summary: dict[str, Any], method: str) -> str:
    """One table per metric: each parameter's indices and their 95 % confidence half-widths, strongest first."""
    columns = INDEX_COLUMNS.get(method, INDEX_COLUMNS["morris"])
    per_metric: dict[str, dict[str, dict[str, Any]]] = {}
    for metric, analysis in (summary.get("analysis") or {}).items():
        per_metric[metric] = (analysis or {}).get("indices") or {}
    if not per_metric:  # no analysis in summary.json: indices.csv
        header, rows = _csv_rows(root / "indices.csv")
        for row in rows:
            record = dict(zip(header, row))
            per_metric.setdefault(record.get("metric", "?"), {})[record.get("parameter", "?")] = {
                k: _numeric(v) for k, v in record.items() if k not in ("metric", "parameter")}
    if not per_metric:
        return '<p class="muted">No analysis in summary.json and no indices.csv.</p>'
    what = ("μ*: mean absolute elementary effect (the metric's change over the parameter's range), σ: their spread "
            "(large against μ*: nonlinear or interacting)" if method == "morris" else
            "S1: first-order (the parameter alone), S_T: total (with its interactions)")
    parts = [f"<p>{h.esc(what)}; ± is the 95 % confidence half-width.</p>"]
    rank = columns[0][0]
    for k, (metric, indices) in enumerate(per_metric.items()):
        parts.append(f"<h3><code>{h.esc(metric)}</code></h3>")
        if not indices:
            parts.append('<p class="muted">Not enough samples to analyse.</p>')
            continue
        ordered = sorted(indices.items(), key=lambda kv: -(_float(kv[1].get(rank))))
        parts.append(h.table(("parameter", *(label for _, label in columns)),
                             [(path, *(values.get(key) for key, _ in columns)) for path, values in ordered],
                             css_id=f"indices-{k}", css_class="indices"))
    return "".join(parts)


def _float(value: Any) -> float:
    try:
        return float(value) if value is not None else float("-inf")
    except (TypeError, ValueError):
        return float("-inf")


def _design_table(header: list[str], rows: list[list[str]], objectives: list[str], variables: list[str], css_id: str,
                  links: dict[str, str] | None = None) -> str:
    """Trials as a table: trial, the objectives (highlighted), the success and constraint columns, the design variables, the rest.

    Objective columns come first so they stay in view on a narrow screen; long dotted names
    wrap at their dots.
    """
    lead = [c for c in ("trial",) if c in header]
    objs = [c for c in objectives if c in header]
    middle = [c for c in ("success_probability", "constraint_violation", "feasible") if c in header]
    design = [c for c in variables if c in header]
    rest = [c for c in header if c not in {*lead, *objs, *middle, *design}]
    order = [*lead, *objs, *middle, *design, *rest]
    index = {c: header.index(c) for c in order}
    head = "".join(f'<th class="{"obj" if c in objs else ("l" if c in ("state", "failure") else "")}" title="{h.esc(c)}">'
                   f"{h.dotted(c)}</th>" for c in order)
    body = []
    for row in rows[:MAX_TABLE_ROWS]:
        cells = []
        for c in order:
            value = row[index[c]] if index[c] < len(row) else ""
            text = h.esc(h.number(_numeric(value)))
            if c == "trial" and links and value in links:
                text = f'<a href="{h.esc(links[value])}">{text}</a>'
            cells.append(f'<td class="l">{text}</td>' if c in ("state", "failure") else f"<td>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    more = f'<p class="muted">{len(rows) - MAX_TABLE_ROWS} more rows in the CSV file.</p>' if len(rows) > MAX_TABLE_ROWS else ""
    return (f'<div class="wide"><table id="{h.esc(css_id)}" class="study"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table></div>{more}")


def optimize_page(root: Path) -> str:
    """A design optimisation: its outcome, objectives and variables, the Pareto front, the best designs, plots."""
    root = Path(root)
    summary = read_json(root / "summary.json")
    sampler = str(summary.get("sampler", "?"))
    label = SAMPLERS.get(sampler, sampler)
    objectives = [o for o in summary.get("objectives") or [] if isinstance(o, dict)]
    obj_labels = [str(o.get("label") or o.get("metric")) for o in objectives]
    variables = [v for v in summary.get("variables") or [] if isinstance(v, dict)]
    var_paths = [str(v.get("path")) for v in variables]
    states = summary.get("states") or {}
    feasible = summary.get("feasible") or 0
    line = (f"{label}: {summary.get('trials', '?')} designs ({states.get('FAIL', 0)} failed, {feasible} feasible), "
            f"{summary.get('evaluations', '?')} evaluations, {summary.get('samples_per_design', 1)} per design")
    if summary.get("cpu_s") is not None:
        line += f"; {summary['cpu_s']:.0f} s CPU"
    sections = [h.banner(bool(summary) and feasible > 0, line)]
    # links to each best design's scenario TOML (best/trial_<n>.toml; a copy beside the summary also counts)
    links = {}
    for best in summary.get("best") or []:
        for candidate in (str(best.get("config") or ""), f"trial_{best.get('trial')}.toml"):
            if candidate and (root / candidate).is_file():
                links[str(best.get("trial"))] = candidate
                break
    header, rows = _csv_rows(root / "pareto.csv")
    front = (_design_table(header, rows, obj_labels, var_paths, "pareto", links) if header
             else '<p class="muted">pareto.csv is missing or empty.</p>')
    sections.append(h.section("Pareto front", f"<p>The feasible non-dominated designs ({len(rows)}); objectives "
                              "highlighted, then the design variables. Each trial links to its scenario TOML "
                              "(<code>continuum-sim run --config</code>) where the folder has it.</p>" + front, "pareto-section"))
    best = [b for b in summary.get("best") or [] if isinstance(b, dict)]
    if best:
        best_header = ["trial", *obj_labels, "success_probability", *var_paths, "config"]
        best_rows = [[str(b.get("trial")), *(str((b.get("values") or {}).get(o, "")) for o in obj_labels),
                      str(b.get("success_probability", "")), *(str((b.get("params") or {}).get(p, "")) for p in var_paths),
                      str(b.get("config", ""))] for b in best]
        sections.append(h.section("Best designs", _design_table(best_header, best_rows, obj_labels, var_paths, "best", links), "best"))
    setup = []
    if objectives:
        setup.append(h.table(("objective", "metric", "aggregate", "direction"),
                             [(o.get("label"), o.get("metric"), o.get("aggregate"), o.get("direction")) for o in objectives],
                             left=4, css_id="objectives"))
    constraints = summary.get("constraints") or []
    if constraints:
        setup.append(h.table(("constraint", "min", "max"), [(c.get("metric"), c.get("min"), c.get("max")) for c in constraints],
                             css_id="constraints"))
    if variables:
        setup.append(h.table(("variable", "low", "high", "log", "integer"),
                             [(v.get("path"), v.get("low"), v.get("high"), bool(v.get("log")), bool(v.get("int"))) for v in variables],
                             css_id="variables"))
    if setup:
        sections.append(h.section("Objectives, constraints, variables", "".join(setup), "setup"))
    sections.append(_plots(root))
    if (root / "trials.csv").is_file():
        t_header, t_rows = _csv_rows(root / "trials.csv")
        sections.append(h.section("Trials", f"<details><summary>trials.csv ({len(t_rows)} trials)</summary>"
                                  + _design_table(t_header, t_rows, obj_labels, var_paths, "trials") + "</details>", "trials"))
    spec = _spec_copy(root, "evaluations/spec.toml", "spec.toml")
    body = _rerun(root, "optimize", spec, "designs and evaluations")
    if spec != "SPEC.toml":
        body += h.preformatted(Path(spec).read_text(), "spec.toml")
    sections.append(h.section("Rerun", body, "rerun"))
    return folder_page(root, f"Design optimisation ({label}) {root.resolve().name}", f"continuum-sim optimize folder {root}", sections)
