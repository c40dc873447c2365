"""Regenerate tests/data/reference_metrics.json and reference_config.toml from the default run.

Run this ONLY in a commit that changes the physics or the defaults on purpose (and say so
in the commit message); ``tests/test_scenario.py::test_default_run_matches_the_stored_reference``
then checks every later commit against it (outcomes exactly, measured values within the
tolerances of tests/data/reference_tolerance.json). ~10 s CPU. Then rerun the drift study
(``python scripts/drift_study.py --write``, ~10 min CPU) so the tolerances match the new reference.

    python scripts/update_reference_metrics.py
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import run_scenario

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        run_scenario(ScenarioConfig.default(), out)
        DATA.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(out / "metrics.json", DATA / "reference_metrics.json")
        shutil.copyfile(out / "config.toml", DATA / "reference_config.toml")
    metrics = json.loads((DATA / "reference_metrics.json").read_text())
    print(f"wrote {DATA / 'reference_metrics.json'}: cutting error mean "
          f"{metrics['cutting_tip_error_mm']['mean']:.4f} mm, detached {metrics['sample_detached']}; "
          "now rerun scripts/drift_study.py --write")


if __name__ == "__main__":
    main()
