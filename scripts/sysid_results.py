"""docs/sysid.md's numbers and tables, collected from the identification and replay folders a stage wrote.

    python scripts/sysid_results.py synthetic docs/sysid/synthetic   # synthetic.csv + identify/
    python scripts/sysid_results.py tdcr3 docs/sysid/tdcr3           # identify/ + replay_json_val/ + replay_identified_val/
    python scripts/sysid_results.py ftdcr docs/sysid/ftdcr_v4        # identify/ + replay_{datasheet,identified,json}_val/
    python scripts/sysid_results.py ftdcr-json docs/sysid/ftdcr_v4_json   # identify/ + replay_identified_val/

Each writes ``DIR/summary.json`` (the numbers the page quotes, under keys without dots, so a
``<!-- from: DIR/summary.json KEY:FMT -> VALUE -->`` marker can name them: a fitted path's dots
become underscores, e.g. ``parameters.arm_sections_0_stiffness_scale.value``) and
``DIR/tables.md`` (the page's tables; ``python scripts/results_tables.py table DIR/tables.md N``
prints the N-th for a ``check-block`` marker). Lengths are in mm, the rope modulus in GPa. It runs
no simulation: the stages of dvc.yaml (``sysid-*``) run ``continuum-sim synthesize / identify /
replay`` and then this script.
"""

from __future__ import annotations

import json
import math
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# display unit per fitted path: (suffix of the path, label, factor from SI)
UNITS = (
    ("cable_hole_radius", "mm", 1e3),
    ("marker_offset.0", "mm", 1e3),
    ("marker_offset.1", "mm", 1e3),
    ("marker_offset.2", "mm", 1e3),
    ("rope_modulus", "GPa", 1e-9),
    ("grinder_mass", "kg", 1.0),
    ("pretension", "N", 1.0),
    ("joint_damping", "N·m·s/rad", 1.0),
)


def _unit(path: str) -> tuple[str, float]:
    for suffix, label, factor in UNITS:
        if path.endswith(suffix):
            return label, factor
    return "", 1.0


def key(path: str) -> str:
    """A fitted path as a summary key (no dots)."""
    return path.replace(".", "_")


def _load(path: Path) -> dict:
    return json.loads(path.read_text())


def _error(replay: dict) -> dict:
    e = replay["position_error_mm"]
    return {"rms": e["rms"], "mean": e["mean"], "max": e["max"], "samples": replay["samples"]}


def identify_summary(folder: Path, hidden: dict[str, float] | None = None) -> dict:
    """The numbers of one identify folder (report.json), in display units."""
    r = _load(folder / "report.json")
    params = {}
    for path, d in r["details"].items():
        unit, f = _unit(path)
        p = {"path": path, "unit": unit, "initial": f * d["initial"], "value": f * d["value"],
             "std_error": f * d["std_error"], "ci95_low": f * d["ci95"][0], "ci95_high": f * d["ci95"][1],
             "identifiable": bool(d["identifiable"]), "why_not": d["why_not"]}
        if hidden is not None and path in hidden:
            p["hidden"] = f * hidden[path]
            p["error_pct"] = 100 * (d["value"] - hidden[path]) / hidden[path]
            p["abs_error_pct"] = abs(p["error_pct"])
        params[key(path)] = p
    out = {
        "parameters": params,
        "n_parameters": len(params),
        "n_identifiable": sum(p["identifiable"] for p in params.values()),
        "train_before": _error(r["replay_before"]),
        "train_after": _error(r["replay_after"]),
        "rmse_before_mm": r["rmse_before_mm"],
        "rmse_after_mm": r["rmse_after_mm"],
        "samples": r["samples"],
        "stride": r["stride"],
        "nfev": r["nfev"],
        "replays": r["replays"],
        "cpu_s": r["cpu_s"],
        "status": r["status"],
        "warnings": r["warnings"],
        "max_abs_correlation": max((abs(c) for i, row in enumerate(r["correlation"].values())
                                    for j, c in enumerate(row) if i != j), default=0.0),
    }
    if "calibration" in r:
        out["calibration"] = r["calibration"]
    return out


def _arm_length_mm(config_toml: Path) -> float:
    data = tomllib.loads(config_toml.read_text())
    return 1e3 * sum(s["length"] for s in data["arm"]["sections"])


def _g(x: float, digits: int = 4) -> str:
    return f"{x:.{digits}g}"


def _signed_pct(x: float) -> str:
    return f"{x:+.2f} %".replace("-", "−")


def synthetic(folder: Path) -> tuple[dict, list[list[str]]]:
    csv = folder / "synthetic.csv"
    header = [line for line in csv.read_text().splitlines()[:4] if line.startswith("#")]
    hidden: dict[str, float] = {}
    noise_mm = noise_deg = float("nan")
    for line in header:
        m = re.search(r"hidden values: (.*)$", line)
        if m:
            for item in m.group(1).split(","):
                path, _, value = item.strip().partition("=")
                hidden[path] = float(value)
        m = re.search(r"noise: ([\d.eE+-]+) mm per axis, ([\d.eE+-]+) deg", line)
        if m:
            noise_mm, noise_deg = float(m.group(1)), float(m.group(2))
    s = identify_summary(folder / "identify", hidden)
    s["noise_mm"] = noise_mm
    s["noise_deg"] = noise_deg
    s["noise_floor_mm"] = math.sqrt(3) * noise_mm
    s["rmse_after_over_floor"] = s["train_after"]["rms"] / s["noise_floor_mm"]
    s["max_abs_error_pct"] = max(abs(p["error_pct"]) for p in s["parameters"].values())
    rows = ["| parameter | hidden | start | identified | std. error | error |", "|---|---|---|---|---|---|"]
    for p in s["parameters"].values():
        unit = f" ({p['unit']})" if p["unit"] else ""
        rows.append(f"| `{p['path']}`{unit} | {_g(p['hidden'])} | {_g(p['initial'])} | {_g(p['value'], 5)} | "
                    f"{_g(p['std_error'], 2)} | {_signed_pct(p['error_pct'])} |")
    return s, [rows]


def _tdcr3_hidden() -> dict[str, float]:
    """The hidden values of the TDCR-3 session (validation/synthetic_tdcr3/make_session.py's truth())."""
    import importlib.util

    from continuum_sim.configio import get_path

    spec = importlib.util.spec_from_file_location("make_session", ROOT / "validation/synthetic_tdcr3/make_session.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    truth = mod.truth()
    paths = [f"arm.sections.{k}.stiffness_scale" for k in range(3)] + ["arm.sections.0.cable_hole_radius",
                                                                       "arm.tools.marker_offset.2"]
    hidden = {p: float(get_path(truth, p)) for p in paths}
    for k, section in enumerate(truth.arm.sections):  # the tendons' true angles in the capture frame
        for c, angle in enumerate(section.cable_angles_deg):
            hidden[f"angle_{k}_{c}"] = float(angle) + float(section.cable_angle_offset_deg)
    return hidden


def tdcr3(folder: Path) -> tuple[dict, list[list[str]]]:
    hidden = _tdcr3_hidden()
    s = identify_summary(folder / "identify", hidden)
    measured = s["calibration"]["after_deg"]  # the angles measured from the pulls
    s["angle_error_deg"] = {f"section_{k}": max(abs((a - hidden[f"angle_{k}_{c}"] + 180.0) % 360.0 - 180.0)
                                                for c, a in enumerate(row)) for k, row in enumerate(measured)}
    length = _arm_length_mm(folder / "recordings" / "robot.toml")
    s["length_mm"] = length
    s["val_json"] = _error(_load(folder / "replay_json_val" / "replay.json"))
    s["val_identified"] = _error(_load(folder / "replay_identified_val" / "replay.json"))
    s["val_json"]["rms_pct_length"] = 100 * s["val_json"]["rms"] / length
    s["val_identified"]["rms_pct_length"] = 100 * s["val_identified"]["rms"] / length
    a, b = s["train_before"], s["train_after"]
    vj, vi = s["val_json"], s["val_identified"]
    rows = [f"| tip position error, mean offset removed (mm) | train RMSE ({a['samples']}) | val RMSE ({vi['samples']}, held out) |",
            "|---|---|---|",
            f"| robot.toml from the JSON, nothing fitted | – | {vj['rms']:.2f} ({vj['rms_pct_length']:.1f} % of {length:.0f} mm) |",
            f"| tendon angles calibrated from the pulls, before the fit | {a['rms']:.2f} | – |",
            f"| **identified** | **{b['rms']:.2f}** | **{vi['rms']:.2f} ({vi['rms_pct_length']:.2f} % of the length)** |"]
    return s, [rows]


def _cells(train: dict | None, val: dict, bold: bool = False) -> str:
    b = "**" if bold else ""
    t = f"{b}{train['rms']:.2f}{b} | {b}{train['mean']:.2f}{b}" if train else "– | –"
    return f"{t} | {b}{val['rms']:.2f}{b} | {b}{val['mean']:.2f}{b}"


def _ftdcr_header(train_samples: int, val_samples: int) -> list[str]:
    return [f"| tip position error (mm, mean offset removed) | train RMSE ({train_samples}) | train mean | "
            f"val RMSE ({val_samples}, held out) | val mean |", "|---|---|---|---|---|"]


def ftdcr(folder: Path) -> tuple[dict, list[list[str]]]:
    """The data sheet's description of FTDCR v4, identified per section; upstream's JSON as it stands."""
    s = identify_summary(folder / "identify")
    s["val_datasheet"] = _error(_load(folder / "replay_datasheet_val" / "replay.json"))
    s["val_identified"] = _error(_load(folder / "replay_identified_val" / "replay.json"))
    s["val_json"] = _error(_load(folder / "replay_json_val" / "replay.json"))
    s["val_over_train_pct"] = 100 * (s["val_identified"]["rms"] / s["train_after"]["rms"] - 1)
    rows = [*_ftdcr_header(s["samples"], s["val_identified"]["samples"]),
            f"| described from the data sheet (`ftdcr_v4.toml`), nothing fitted | {_cells(s['train_before'], s['val_datasheet'])} |",
            f"| **identified per section** from `ftdcr_v4.toml` | {_cells(s['train_after'], s['val_identified'], True)} |",
            f"| `robot.toml` from upstream's JSON (`import-robot`), nothing fitted | {_cells(None, s['val_json'])} |"]
    return s, [rows]


def ftdcr_json(folder: Path) -> tuple[dict, list[list[str]]]:
    """FTDCR v4 from upstream's JSON: tendon angles calibrated from the pulls, then the six per-section values."""
    s = identify_summary(folder / "identify")
    s["val_identified"] = _error(_load(folder / "replay_identified_val" / "replay.json"))
    rows = [*_ftdcr_header(s["samples"], s["val_identified"]["samples"]),
            f"| `robot.toml` from upstream's JSON, `--calibrate-angles` + the six per-section parameters | "
            f"{_cells(s['train_after'], s['val_identified'])} |"]
    return s, [rows]


KINDS = {"synthetic": synthetic, "tdcr3": tdcr3, "ftdcr": ftdcr, "ftdcr-json": ftdcr_json}


def main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0] not in KINDS:
        print(f"usage: python scripts/sysid_results.py {{{'|'.join(KINDS)}}} DIR", file=sys.stderr)
        return 2
    folder = Path(argv[1])
    summary, tables = KINDS[argv[0]](folder)
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (folder / "tables.md").write_text("\n\n".join("\n".join(t) for t in tables) + "\n")
    print(f"wrote {folder}/summary.json, {folder}/tables.md")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
