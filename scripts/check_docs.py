"""Rerun the commands behind the numbers in the docs and fail when a number no longer matches.

    python scripts/check_docs.py            # the cheap checks (CI, .ci/run: < 60 s on 2 cores)
    python scripts/check_docs.py --all      # also the slow ones (marked check-slow / check-block-slow)
    python scripts/check_docs.py --list     # what would run
    python scripts/check_docs.py --fix      # rewrite the numbers and blocks that no longer match
    python scripts/check_docs.py count-tests tests/test_plant.py   # a helper the markers use: "13 tests"

A number in README.md or docs/*.md is tied to the command that gives it by an HTML comment
(invisible when rendered):

* inline, right after the number: ``13 tests <!-- check: python scripts/check_docs.py count-tests
  tests/test_plant.py -> 13 tests -->``. The command's last stdout line must equal the value
  after ``->``, and that value must also appear in the same line's text before the marker (so
  the prose and the check cannot drift apart).
* a number from a command that prints JSON (as ``continuum-sim replay`` does):
  ``9.22 <!-- check: continuum-sim replay REC.csv --out /tmp/x | position_error_mm.rms:.2f -> 9.22 -->``;
  the first JSON object in the command's stdout, the dotted key, formatted with the format
  spec. Markers naming the same command run it once.
* a block (a table): ``<!-- check-block: python scripts/sweep_table.py SPEC -->`` on its own
  line; the lines after it up to the first blank line must equal the command's stdout.

* a number from a published result (an output of a stage of ``dvc.yaml``, docs/architecture.md):
  ``0.10 <!-- from: docs/results/default_runs.json closed.cutting_tip_error_mm.mean:.2f -> 0.10 -->``
  reads the dotted key of that JSON file (no command runs; the results pipeline keeps the file current).

``--fix`` rewrites what does not match with what the commands and files give (a block's lines, an
inline value in its marker and in the text before it): run it after ``python scripts/results.py repro``.

``check-slow`` / ``check-block-slow`` mark commands too slow for every CI run (minutes); they
run with ``--all``. In commands, ``python`` means this interpreter and ``continuum-sim`` the
package's CLI (``python -m continuum_sim``); they run from the repository root with it on
``PYTHONPATH``. Numbers that depend on the machine (times) carry their command in the prose
and no marker. Exit 0 when every check matches, 1 otherwise (each mismatch printed).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ("README.md", "docs/*.md")
INLINE = re.compile(r"<!--\s*check(?P<slow>-slow)?:\s*(?P<cmd>.+?)\s*->\s*(?P<value>.+?)\s*-->")
FROM = re.compile(r"<!--\s*from:\s*(?P<file>\S+)\s+(?P<key>\S+?)\s*->\s*(?P<value>.+?)\s*-->")
BLOCK = re.compile(r"^\s*<!--\s*check-block(?P<slow>-slow)?:\s*(?P<cmd>.+?)\s*-->\s*$")
TIMEOUT_S = 300


@dataclass
class Check:
    file: str
    line: int
    command: str
    expected: str
    slow: bool
    block: bool
    text_before: str = ""


def find_checks(root: Path = ROOT) -> list[Check]:
    """Every marker in ``root``'s README.md and docs/*.md, in file order."""
    checks = []
    for pattern in DOCS:
        for path in sorted(root.glob(pattern)):
            lines = path.read_text().splitlines()
            rel = str(path.relative_to(root))
            for i, line in enumerate(lines):
                block = BLOCK.match(line)
                if block:
                    body = []
                    for following in lines[i + 1:]:
                        if not following.strip():
                            break
                        body.append(following)
                    checks.append(Check(rel, i + 1, block["cmd"], "\n".join(body), bool(block["slow"]), True))
                    continue
                for m in INLINE.finditer(line):
                    checks.append(Check(rel, i + 1, m["cmd"], m["value"], bool(m["slow"]), False, line[: m.start()]))
                for m in FROM.finditer(line):
                    checks.append(Check(rel, i + 1, f"cat {m['file']} | {m['key']}", m["value"], False, False, line[: m.start()]))
    return checks


def _argv(command: str) -> list[str]:
    argv = shlex.split(command)
    if argv[0] == "python":
        return [sys.executable, *argv[1:]]
    if argv[0] == "continuum-sim":
        return [sys.executable, "-m", "continuum_sim", *argv[1:]]
    return argv


_OUTPUTS: dict[tuple[str, str], subprocess.CompletedProcess] = {}  # (root, command) -> its run: each command runs once


def _execute(command: str, root: Path) -> subprocess.CompletedProcess | str:
    key = (str(root), command)
    if key not in _OUTPUTS:
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        env.setdefault("MUJOCO_GL", "egl")
        try:
            _OUTPUTS[key] = subprocess.run(_argv(command), cwd=root, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            return f"timed out after {TIMEOUT_S} s"
    return _OUTPUTS[key]


def _json_value(stdout: str, key: str, spec: str) -> str:
    """``key`` (dotted) of the first JSON object in ``stdout``, formatted with ``spec``."""
    starts = [i for i in (stdout.find("{"), stdout.find("[")) if i >= 0]
    start = min(starts) if starts else -1
    if start < 0:
        raise ValueError("the command printed no JSON object")
    value = json.JSONDecoder().raw_decode(stdout[start:])[0]
    for part in key.split("."):
        value = value[int(part)] if isinstance(value, list) else value[part]
    return format(value, spec)


def run(check: Check, root: Path = ROOT) -> str | None:
    """None when the check holds, else what is wrong (the command runs in ``root``)."""
    got = produce(check, root)
    if isinstance(got, Problem):
        return str(got)
    if not check.block and check.expected not in check.text_before:
        return f"the marker's value {check.expected!r} is not in the text before it"
    if got != check.expected.strip():
        return f"the docs say\n{check.expected}\nthe command gives\n{got}"
    return None


class Problem(str):
    """Why a check's command gave no value."""


def produce(check: Check, root: Path = ROOT) -> str | Problem:
    """What the check's command (or file) gives now."""
    command, _, extract = check.command.partition(" | ")
    done = _execute(command.strip(), root)
    if isinstance(done, str):
        return Problem(done)
    if done.returncode != 0:
        return Problem(f"exit {done.returncode}: {done.stderr.strip().splitlines()[-1:] or done.stdout.strip()[-200:]}")
    out = done.stdout.strip()
    if extract:
        key, _, spec = extract.strip().partition(":")
        try:
            return _json_value(out, key, spec)
        except (ValueError, KeyError, TypeError) as exc:
            return Problem(f"{extract.strip()}: {type(exc).__name__}: {exc}")
    return out if check.block else (out.splitlines() or [""])[-1].strip()


def fix(checks: list[Check], root: Path = ROOT) -> int:
    """Rewrite each page so its checks hold; the number of values changed."""
    changed = 0
    by_file: dict[str, list[Check]] = {}
    for c in checks:
        by_file.setdefault(c.file, []).append(c)
    for rel, items in by_file.items():
        path = root / rel
        lines = path.read_text().splitlines()
        # bottom up (a block's new length moves no check above it), right to left within a line (an edit
        # moves no marker left of it)
        for c in sorted(items, key=lambda c: (-c.line, -len(c.text_before))):
            got = produce(c, root)
            if isinstance(got, Problem) or got == c.expected.strip():
                continue
            i = c.line - 1
            if c.block:
                end = i + 1
                while end < len(lines) and lines[end].strip():
                    end += 1
                lines[i + 1 : end] = got.splitlines()
            else:
                line = lines[i]
                marker_at = line.find("-> " + c.expected, len(c.text_before))
                if marker_at < 0:
                    continue
                head = c.text_before
                at = head.rfind(c.expected)
                if at >= 0:
                    head = head[:at] + got + head[at + len(c.expected):]
                tail = line[len(c.text_before):].replace("-> " + c.expected, "-> " + got, 1)
                lines[i] = head + tail
            changed += 1
        path.write_text("\n".join(lines) + "\n")
    return changed


def count_tests(path: str) -> str:
    """'N tests': the test items pytest collects from ``path`` (parametrised cases count one each)."""
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", path], cwd=ROOT,
                          capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    n = sum(1 for line in done.stdout.splitlines() if "::" in line)
    return f"{n} tests"


def main(argv: list[str]) -> int:
    if argv[:1] == ["count-tests"] and len(argv) == 2:
        print(count_tests(argv[1]))
        return 0
    slow = "--all" in argv
    checks = [c for c in find_checks() if slow or not c.slow]
    if "--list" in argv:
        for c in checks:
            print(f"{c.file}:{c.line}: {'[slow] ' if c.slow else ''}{c.command}")
        return 0
    if "--fix" in argv:
        print(f"check_docs: {fix(checks)} values rewritten")
    failures = 0
    start = time.perf_counter()
    for c in checks:
        t0 = time.perf_counter()
        problem = run(c)
        status = "ok" if problem is None else "MISMATCH"
        print(f"{status:8} {c.file}:{c.line} ({time.perf_counter() - t0:.1f} s) {c.command}")
        if problem:
            failures += 1
            print("         " + problem.replace("\n", "\n         "))
    skipped = sum(1 for c in find_checks() if c.slow) if not slow else 0
    print(f"check_docs: {len(checks) - failures}/{len(checks)} checks match ({skipped} slow ones skipped; --all runs them) "
          f"in {time.perf_counter() - start:.0f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
