"""HTML building blocks of the report pages: escaped text, tables, embedded images, one page shell.

Every page is one file: CSS inline, images as base64 ``data:`` URIs, no script or font
fetched from anywhere, so it reads offline and can be mailed or archived as it is. The
only outside reference is a run's video (``<video src="video.mp4">``, a relative link to
the file next to the page; see docs/report.md for why it is not embedded).
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:0 auto;max-width:1200px;padding:1em 2em;color:#222}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em}th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f3f3f3}td.l,th.l{text-align:left}
.ok{color:#14671f;font-weight:bold}.bad{color:#a31515;font-weight:bold}.muted{color:#777}
figure{margin:.5em 1em .5em 0;display:inline-block;vertical-align:top;max-width:100%}figure img{max-width:100%;border:1px solid #ddd}
.wide{overflow-x:auto;max-width:100%}figcaption{font-size:.85em;color:#555}
pre{background:#f7f7f7;padding:.6em;overflow:auto;font-size:.8em;max-height:40em}
video{max-width:100%;border:1px solid #ddd}
.banner{padding:.6em 1em;border-radius:4px;margin:.6em 0;font-size:1.1em}
.banner.ok{background:#e6f4e8}.banner.bad{background:#fbe9e9}
table.params td{vertical-align:top}table.params td.src{min-width:16em;max-width:30em;white-space:normal;font-size:.9em}
table.params td.path{font-family:monospace;font-size:.9em;white-space:nowrap}tr.ovr td{background:#fff6d6}td.rng{white-space:nowrap}
table.study th{white-space:normal;max-width:9em;vertical-align:bottom}table.study th.obj{background:#e8eefb}
code.cmd{display:block;background:#f7f7f7;padding:.4em .6em;margin:.3em 0;white-space:pre-wrap;word-break:break-all}
h3{font-size:1em;margin:1em 0 .2em}
"""


def read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; {} when missing or unreadable (the page says what is missing)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def esc(value: Any) -> str:
    """Text escaped for HTML."""
    return html.escape(str(value), quote=True)


def number(value: Any, digits: int = 4) -> str:
    """A number for a table cell: ``digits`` significant figures, '–' for None/NaN, yes/no for booleans."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            return "–"
        value += 0.0  # -0.0 shows as 0
        return f"{value:.{digits}g}"
    return str(value)


def table(headers: Sequence[str], rows: Iterable[Sequence[Any]], *, left: int = 1, css_id: str | None = None,
          raw: bool = False, css_class: str | None = None, raw_headers: bool = False) -> str:
    """An HTML table; the first ``left`` columns left-aligned (names), the rest right-aligned (numbers).

    ``raw``: cells are already HTML (links); otherwise they are escaped. ``raw_headers``: the
    header cells are already HTML (whole ``<th>`` elements are still built here).
    """
    ident = (f' id="{esc(css_id)}"' if css_id else "") + (f' class="{esc(css_class)}"' if css_class else "")
    label = (lambda text: text) if raw_headers else esc
    head = "".join(f'<th class="l">{label(h)}</th>' if i < left else f"<th>{label(h)}</th>" for i, h in enumerate(headers))
    body = []
    for row in rows:
        cells = []
        for i, cell in enumerate(row):
            text = cell if raw and isinstance(cell, str) else esc(number(cell))
            cells.append(f'<td class="l">{text}</td>' if i < left else f"<td>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<div class=\"wide\"><table{ident}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>"


def image(path: Path, caption: str | None = None) -> str:
    """A PNG (or JPEG/SVG) embedded as a data URI, with its file name as caption."""
    suffix = path.suffix.lower().lstrip(".")
    mime = {"png": "image/png", "jpg": "image/jpeg", "jpeg": "image/jpeg", "svg": "image/svg+xml"}.get(suffix, "image/png")
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    label = esc(caption if caption is not None else path.name)
    return (f'<figure><img class="plot" alt="{esc(path.name)}" src="data:{mime};base64,{data}">'
            f"<figcaption>{label}</figcaption></figure>")


def images(paths: Iterable[Path], root: Path) -> str:
    """Every image, captioned with its path relative to ``root``."""
    return "".join(image(p, str(p.relative_to(root))) for p in paths)


def plot_files(folder: Path) -> list[Path]:
    """The PNGs of a folder and its ``plots/`` (sorted; skips nothing)."""
    found = sorted(folder.glob("*.png"))
    if (folder / "plots").is_dir():
        found += sorted((folder / "plots").glob("*.png"))
    return found


def preformatted(text: str, summary: str, open_: bool = False) -> str:
    """A collapsible block of text (a config file, raw JSON)."""
    return f"<details{' open' if open_ else ''}><summary>{esc(summary)}</summary><pre>{esc(text)}</pre></details>"


def json_block(data: Any, summary: str) -> str:
    return preformatted(json.dumps(data, indent=2, sort_keys=True, default=str), summary)


def banner(ok: bool, text: str) -> str:
    """The outcome line at the top of a page (green when ``ok``, red otherwise)."""
    cls = "ok" if ok else "bad"
    return f'<div class="banner {cls}" id="outcome"><span class="{cls}">{esc(text)}</span></div>'


def dotted(name: str) -> str:
    """A dotted parameter or metric path escaped, with break opportunities after its dots and underscores (narrow headers)."""
    import re

    return "".join(esc(part) + "<wbr>" if part.endswith((".", "_")) else esc(part) for part in re.split(r"(?<=[._])", name))


def command(argv: Sequence[str]) -> str:
    """A shell command line to copy, as a block of code."""
    import shlex

    return f'<code class="cmd">{esc(shlex.join(argv))}</code>'


def section(title: str, body: str, css_id: str | None = None) -> str:
    ident = f' id="{esc(css_id)}"' if css_id else ""
    return f"<section{ident}><h2>{esc(title)}</h2>{body}</section>"


def page(title: str, subtitle: str, sections: Sequence[str]) -> str:
    """The whole document."""
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{esc(title)}</title>"
        f"<style>{CSS}</style></head><body><h1>{esc(title)}</h1><p class=\"muted\">{esc(subtitle)}</p>"
        + "".join(sections)
        + "</body></html>\n"
    )
