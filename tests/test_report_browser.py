"""report.html as a browser renders it: headless Chromium loads the page offline, and the rendered DOM must hold
the metrics table, every plot decoded to a non-zero size, the video element with its poster, the parameter registry's
table and the provenance (the run's page, a sweep's, a sensitivity study's), and an optimisation's Pareto table with its
objective columns inside a 1,400 px wide window.

The browser is Debian's ``chromium`` (``.ci/run`` installs it with apt-get when it runs as root); the test
skips, saying why, only where none is installed.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from report_helpers import PROVENANCE

from continuum_sim.report import write_report

REPO = Path(__file__).resolve().parent.parent

WIDTH = 1400  # px: the window the pages are checked at (a laptop screen)
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--no-first-run",
         "--disable-dev-shm-usage")
# Appended to a COPY of the page under test (the page itself ships no script): after load, write what the
# browser rendered into the DOM, which --dump-dom then prints.
PROBE = """<script>
window.addEventListener('load', () => {
  const imgs = [...document.querySelectorAll('img.plot')].map(i => [i.naturalWidth, i.naturalHeight, i.complete]);
  const v = document.querySelector('video');
  const t = document.querySelector('table#metrics');
  const rows = sel => { const e = document.querySelector(sel); return e ? e.querySelectorAll('tbody tr').length : 0; };
  const objectives = [...document.querySelectorAll('table#pareto th.obj')].map(th => {
    const r = th.getBoundingClientRect(); return [th.title, r.left, r.right]; });
  const out = {images: imgs, video: v ? {src: v.getAttribute('src'), controls: v.controls, poster: v.getAttribute('poster')} : null,
               metrics_rows: t ? t.querySelectorAll('tbody tr').length : 0,
               parameter_rows: rows('table#parameters'), index_tables: document.querySelectorAll('table.indices').length,
               provenance: (document.querySelector('#provenance-section') || {}).textContent || null,
               title: document.title, viewport: window.innerWidth, objectives: objectives,
               outcome: (document.querySelector('#outcome') || {}).textContent || null};
  const pre = document.createElement('pre'); pre.id = 'probe'; pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>"""


def _browser() -> str:
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no Chromium/Chrome found (tried " + ", ".join(BROWSERS) + "); install Debian's `chromium` "
                "(apt-get install -y chromium; .ci/run does this when run as root)")


def _render(page: Path, tmp: Path, screenshot: Path | None = None) -> dict:
    """The probe's findings from the DOM Chromium rendered for ``page`` (and a screenshot if asked)."""
    browser = _browser()
    probe = page.with_name(page.stem + ".probe.html")
    probe.write_text(page.read_text().replace("</body>", PROBE + "</body>"))
    common = [browser, *FLAGS, f"--user-data-dir={tmp / 'profile'}", "--virtual-time-budget=5000", f"--window-size={WIDTH},1000"]
    dom = subprocess.run([*common, "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120, check=True).stdout
    match = re.search(r'<pre id="probe">(.*?)</pre>', dom, re.S)
    assert match, f"the probe did not run; DOM starts: {dom[:300]!r}"
    if screenshot is not None:
        subprocess.run([*common, f"--window-size={WIDTH},1600", f"--screenshot={screenshot}", page.as_uri()], capture_output=True,
                       timeout=120, check=True)
    import html

    return json.loads(html.unescape(match.group(1)))


def test_run_report_renders_metrics_plots_and_video(tmp_path, report_run):
    run = tmp_path / "run"
    shutil.copytree(report_run, run)
    page = write_report(run)
    shot = tmp_path / "run.png"
    found = _render(page, tmp_path, shot)
    assert found["metrics_rows"] >= 10
    n_plots = len(list((run / "plots").glob("*.png")))
    assert len(found["images"]) == n_plots >= 6
    assert all(w > 100 and h > 100 and done for w, h, done in found["images"]), found["images"]
    assert found["video"] == {"src": "video.mp4", "controls": True, "poster": "poster.png"}
    assert (run / "poster.png").read_bytes().startswith(b"\x89PNG")
    assert found["parameter_rows"] >= 25  # the registry's parameters.json, one row each
    assert "Provenance" in found["provenance"]
    assert "task failed: partial_run" in found["outcome"]
    assert shot.stat().st_size > 10_000


def test_sweep_report_renders_the_comparison_table_and_plots(tmp_path, report_sweep):
    sweep = tmp_path / "sweep"
    shutil.copytree(report_sweep, sweep)
    found = _render(sweep / "report.html", tmp_path)
    assert found["metrics_rows"] == 2
    assert len(found["images"]) == len(list((sweep / "plots").glob("*.png"))) >= 2
    assert all(w > 100 and h > 100 for w, h, _ in found["images"])
    assert found["video"] is None


def test_sensitivity_report_is_titled_by_its_method_and_holds_one_index_table_per_metric(tmp_path):
    folder = tmp_path / "quick_open"
    shutil.copytree(REPO / "docs" / "sensitivity" / "quick_open", folder)
    (folder / "provenance.json").write_text(json.dumps(PROVENANCE))
    found = _render(write_report(folder), tmp_path)
    assert found["title"] == "Sensitivity study (Morris) quick_open"
    assert found["index_tables"] == len(json.loads((folder / "summary.json").read_text())["metrics"])
    assert "0123456789ab (dirty)" in found["provenance"]
    assert all(w > 100 and h > 100 for w, h, _ in found["images"]) and len(found["images"]) == 2


def test_optimize_report_keeps_the_objective_columns_in_view_at_1400_px(tmp_path):
    folder = tmp_path / "task_tpe"
    shutil.copytree(REPO / "docs" / "optimize" / "task_tpe", folder)
    found = _render(write_report(folder), tmp_path)
    assert found["title"] == "Design optimisation (TPE) task_tpe" and found["viewport"] == WIDTH
    objectives = [o["label"] for o in json.loads((folder / "summary.json").read_text())["objectives"]]
    assert [name for name, _, _ in found["objectives"]] == objectives
    assert all(0 <= left < right <= WIDTH for _, left, right in found["objectives"]), found["objectives"]
