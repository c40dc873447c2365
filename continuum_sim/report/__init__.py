"""One self-contained HTML page per run folder and per study folder (``report.html``).

``write_report(folder)`` detects what the folder holds (a run, a sweep, a validation
report, an identification, or any other study with a JSON/CSV summary and PNGs) and writes
``report.html`` into it: the outcome, the key metrics with units, every plot (base64-
embedded, so the page reads offline), the parameters and the configuration. Pure file
reading and string building: no MuJoCo, no GL.
"""

from __future__ import annotations

from .pages import detect_kind, report_page, write_report

__all__ = ["detect_kind", "report_page", "write_report"]
