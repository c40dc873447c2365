"""Run a sweep spec into a temporary folder and print its results as the Markdown table of the docs.

    python scripts/sweep_table.py docs/sweeps/stiffness_gravity_sag.toml

One row per variant in grid order: the swept parameters (3 significant figures), then each of
the spec's metrics to 2 decimals. docs/sweeps.md quotes this output verbatim, and
``scripts/check_docs.py`` reruns it (``check-block`` marker) and fails when they differ.
"""

from __future__ import annotations

import contextlib
import csv
import io
import sys
import tempfile
from pathlib import Path

HEADINGS = {  # metric -> column heading in the docs
    "sag_mm": "sag mm", "sag_z_mm": "sag down mm", "pcc_error_mm": "tip error vs PCC mm",
    "shape_error_mm": "error without gravity mm", "max_cable_tension_n": "max cable tension N",
    "min_cable_tension_n": "min cable tension N",
}


def table(spec_path: str) -> str:
    from continuum_sim.cli import main
    from continuum_sim.sweep import load_spec

    spec = load_spec(spec_path, progress=False)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sweep"
        with contextlib.redirect_stdout(io.StringIO()):  # the sweep's own summary line
            code = main(["sweep", spec_path, "--out", str(out), "--quiet"])
        if code != 0:
            raise SystemExit(f"sweep_table: the sweep failed (exit {code})")
        with (out / "results.csv").open(newline="") as fh:
            rows = list(csv.DictReader(fh))
    params = list(spec.paths)
    names = [p.split(".")[-1].replace("_", " ") for p in params] + [HEADINGS.get(m, m) for m in spec.metrics]
    lines = ["| " + " | ".join(names) + " |", "|" + "---:|" * len(names)]
    for row in rows:
        cells = [f"{float(row[p]):.3g}" for p in params]
        cells += ["failed" if row[m] in ("", "None") else f"{float(row[m]) + 0.0:.2f}" for m in spec.metrics]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python scripts/sweep_table.py SPEC.toml")
    print(table(sys.argv[1]))
