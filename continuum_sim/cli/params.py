"""``continuum-sim params``: the parameter registry with the values of a resolved configuration.

``docs/parameters.md`` is this command's markdown output at the shipped defaults
(``continuum-sim params --format markdown > docs/parameters.md``; a test keeps them in step).
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..params.registry import REGISTRY, Parameter, apply, parse_overrides, records

MARKDOWN_HEADER = """\
# Parameters

Every physical parameter of the plant, its value at the shipped defaults, unit, status and
source, and the plausible range of each assumed one (the range sensitivity studies and
design optimisers sample; `log`: sampled logarithmically). Generated from the registry
(`continuum_sim/params/registry.py`) by

    continuum-sim params --format markdown > docs/parameters.md

(a test fails when this file is stale). Status: **measured** (the prototype's figures),
**derived** (from the parameters named), **assumed** (our choice, with the reason),
**fitted** (identified from data). Paths are the scenario-config paths a scenario TOML, a
sweep spec or `continuum-sim params --set PATH=VALUE` uses. Each run folder records the
values it used in `parameters.json`.

"""


def _number(value: float) -> str:
    return f"{value:.6g}"


def _rows(doc: dict[str, Any]) -> list[dict[str, Any]]:
    return list(doc["parameters"])


def render_markdown(doc: dict[str, Any]) -> str:
    """The registry as a markdown table (the body of docs/parameters.md)."""
    counts = {s: sum(1 for r in doc["parameters"] if r["status"] == s) for s in ("measured", "derived", "assumed", "fitted")}
    summary = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
    lines = [MARKDOWN_HEADER.rstrip("\n"), "", f"{len(doc['parameters'])} parameters: {summary}.", ""]
    lines.append("| path | value | unit | status | plausible range | source |")
    lines.append("|---|---|---|---|---|---|")
    for r in _rows(doc):
        low_high = "" if r["range"] is None else f"{_number(r['range'][0])} – {_number(r['range'][1])}" + (" (log)" if r["log"] else "")
        value = _number(r["value"]) + (" *(set)*" if r["overridden"] else "")
        source = r["source"].replace("|", "/")
        lines.append(f"| `{r['path']}` | {value} | {r['unit']} | {r['status']} | {low_high} | {r['name']}: {source} |")
    return "\n".join(lines) + "\n"


def render_table(doc: dict[str, Any], width: int = 60) -> str:
    """Plain text: one line per parameter (the source cut to ``width`` characters)."""
    rows = [("path", "value", "unit", "status", "range", "source")]
    for r in _rows(doc):
        low_high = "" if r["range"] is None else f"{_number(r['range'][0])}..{_number(r['range'][1])}" + (" log" if r["log"] else "")
        mark = "*" if r["overridden"] else ""
        source = r["source"] if len(r["source"]) <= width else r["source"][: width - 1] + "…"
        rows.append((r["path"], _number(r["value"]) + mark, r["unit"], r["status"], low_high, source))
    widths = [max(len(row[i]) for row in rows) for i in range(5)]
    out = ["  ".join(cell.ljust(w) for cell, w in zip(row[:5], widths)) + "  " + row[5] for row in rows]
    if doc["overrides"]:
        out.append("* set by --set/--config: " + ", ".join(f"{k} = {v:g}" for k, v in doc["overrides"].items()))
    return "\n".join(out) + "\n"


def render(doc: dict[str, Any], fmt: str) -> str:
    if fmt == "json":
        return json.dumps(doc, indent=1, ensure_ascii=False) + "\n"
    if fmt == "markdown":
        return render_markdown(doc)
    return render_table(doc)


def document(config_path: str | None = None, sets: list[str] | tuple[str, ...] = ()) -> dict[str, Any]:
    """The registry document for the config at ``config_path`` (default: shipped) with ``sets`` applied."""
    from ..scenario.config import ScenarioConfig

    default = ScenarioConfig.default()
    config = default if config_path is None else ScenarioConfig.from_toml(config_path)
    overrides = parse_overrides(list(sets))
    config = apply(config, overrides)
    doc = records(config, default)
    doc["overrides"] = {**doc["overrides"], **overrides}
    for row in doc["parameters"]:
        row["overridden"] = row["path"] in doc["overrides"]
    return doc


def cmd_params(args: argparse.Namespace) -> int:
    print(render(document(args.config, args.set or ()), args.format), end="")
    return 0


def add_params_parser(sub: Any) -> None:
    """Register ``params`` on the CLI's subparsers."""
    p = sub.add_parser("params", help="the parameter registry: value, unit, status, source, plausible range (docs/parameters.md)")
    p.add_argument("--config", help="scenario TOML file (default: the shipped defaults)")
    p.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="set a registry parameter, e.g. model.cable_friction.mu=0.1 (repeatable; must lie in its range)")
    p.add_argument("--format", choices=("table", "json", "markdown"), default="table")
    p.set_defaults(func=cmd_params)


__all__ = ["Parameter", "REGISTRY", "add_params_parser", "cmd_params", "document", "render", "render_markdown"]
