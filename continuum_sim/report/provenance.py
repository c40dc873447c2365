"""The Provenance section every page ends with, and the page shell that adds it.

``provenance.json`` (next to a run's or a study's results) records what made the folder: the
command, the git commit and whether the tree was dirty, a hash of the package's code, hashes of
the configuration, the parameter registry and the study spec, the library versions and the
machine. The page shows it as one small table, so a result can be traced to the code and
inputs that produced it; a folder without the file says so in one line.
"""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from . import html as h

PROVENANCE_NAME = "provenance.json"
SHORT = 12  # characters of a hash or commit shown (the file holds them whole)
MAX_CHANGED = 20  # changed files listed by name under a dirty commit


def _short(value: Any) -> str:
    return str(value)[:SHORT] if value else "–"


def provenance_rows(data: dict[str, Any]) -> list[tuple[str, str]]:
    """(label, text) rows of a ``provenance.json`` document; absent entries are left out."""
    rows: list[tuple[str, str]] = []
    argv = data.get("argv")
    if isinstance(argv, list) and argv:
        rows.append(("command", shlex.join(str(a) for a in argv)))
    elif data.get("command"):
        rows.append(("command", str(data["command"])))
    if data.get("created_utc"):
        rows.append(("created (UTC)", str(data["created_utc"])))
    package = data.get("package") or {}
    if package:
        rows.append(("package", f"{package.get('name', '?')} {package.get('version', '?')}"))
    git = data.get("git") or {}
    if git:
        commit = _short(git.get("commit")) if git.get("commit") else "(not a git checkout)"
        changed = [str(c) for c in git.get("changed") or []]
        text = commit + (" (dirty)" if git.get("dirty") else "")
        if changed:
            more = f" and {len(changed) - MAX_CHANGED} more" if len(changed) > MAX_CHANGED else ""
            text += "; changed: " + ", ".join(changed[:MAX_CHANGED]) + more
        rows.append(("git commit", text))
    if data.get("code_sha256"):
        rows.append(("code sha256", _short(data["code_sha256"])))
    for name, value in (data.get("hashes") or {}).items():
        if value:
            rows.append((f"{name} hash", _short(value)))
    versions = data.get("versions") or {}
    if versions:
        rows.append(("versions", ", ".join(f"{k} {v}" for k, v in versions.items() if v is not None)))
    machine = data.get("machine") or {}
    if machine:
        cpu = f"{machine.get('cpu') or '?'} ({machine.get('cpu_count', '?')} cores)"
        rows.append(("machine", f"{machine.get('platform') or '?'}; {cpu}"))
        threads = machine.get("threads") or {}
        if threads:
            rows.append(("threads", ", ".join(f"{k}={v}" for k, v in threads.items() if v is not None) or "–"))
    return rows


def provenance_section(folder: Path) -> str:
    """The "Provenance" section of ``folder``'s page: ``provenance.json`` as a table, or one muted line without it."""
    path = Path(folder) / PROVENANCE_NAME
    if not path.is_file():
        body = f'<p class="muted">No {PROVENANCE_NAME} in this folder: the commit, code, versions and machine that made it are not recorded.</p>'
    else:
        rows = provenance_rows(h.read_json(path))
        body = (h.table(("what", "recorded"), rows, left=2, css_id="provenance") if rows
                else f'<p class="bad">{PROVENANCE_NAME} is unreadable or empty.</p>')
    return h.section("Provenance", body, "provenance-section")


def folder_page(folder: Path, title: str, subtitle: str, sections: Sequence[str]) -> str:
    """The whole document of ``folder``'s page: ``sections`` and, last, its Provenance (every page kind ends with it)."""
    return h.page(title, subtitle, [*sections, provenance_section(folder)])
