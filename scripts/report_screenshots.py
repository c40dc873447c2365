"""Screenshots of a run's and a sweep's report.html for the docs (docs/report_run.png, docs/report_sweep.png).

    continuum-sim run --video --out runs/default
    continuum-sim sweep docs/sweeps/stiffness_gravity_sag.toml --out sweeps/stiffness
    python scripts/report_screenshots.py runs/default sweeps/stiffness

Rewrites each folder's report.html (``continuum-sim report``), renders its top 1280×1700 px in
headless Chromium (Debian's ``chromium``) and stores it downscaled to 900 px wide, 256 colours.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def screenshot(folder: Path, target: Path) -> None:
    from PIL import Image

    from continuum_sim.report import write_report

    page = write_report(folder)
    browser = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if browser is None:
        raise SystemExit("report_screenshots: no Chromium found (apt-get install -y chromium)")
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "shot.png"
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--no-first-run",
                        f"--user-data-dir={tmp}/profile", "--hide-scrollbars", "--window-size=1280,1700", f"--screenshot={raw}",
                        page.resolve().as_uri()], check=True, capture_output=True, timeout=120)
        image = Image.open(raw).convert("RGB")
        small = image.resize((900, round(image.height * 900 / image.width)), Image.Resampling.LANCZOS)
        small.quantize(colors=256).save(target, optimize=True)
    print(f"wrote {target} ({target.stat().st_size / 1e3:.0f} kB) from {page}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit("usage: python scripts/report_screenshots.py RUN_DIR SWEEP_DIR")
    screenshot(Path(sys.argv[1]), ROOT / "docs" / "report_run.png")
    screenshot(Path(sys.argv[2]), ROOT / "docs" / "report_sweep.png")
