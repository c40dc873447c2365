"""scripts/check_docs.py: a number in the docs is checked against its command, and a stale one fails."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _module():
    spec = importlib.util.spec_from_file_location("check_docs", ROOT / "scripts" / "check_docs.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


def test_inline_and_block_markers_pass_when_true_and_fail_when_stale(tmp_path):
    cd = _module()
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text(
        'The answer is 42 <!-- check: python -c "print(6 * 7)" -> 42 -->.\n'
        'Stale: 41 <!-- check: python -c "print(6 * 7)" -> 41 -->.\n'
        'Drifted prose: 40 <!-- check: python -c "print(6 * 7)" -> 42 -->.\n'
        'Slow: 42 <!-- check-slow: python -c "print(6 * 7)" -> 42 -->\n')
    (tmp_path / "docs" / "t.md").write_text(
        '<!-- check-block: python -c "print(\'| a |\'); print(\'| 1 |\')" -->\n| a |\n| 1 |\n\n'
        '<!-- check-block: python -c "print(\'| a |\'); print(\'| 2 |\')" -->\n| a |\n| 1 |\n\ntext\n')
    checks = cd.find_checks(tmp_path)
    assert [(c.file, c.line, c.block, c.slow) for c in checks] == [
        ("README.md", 1, False, False), ("README.md", 2, False, False), ("README.md", 3, False, False),
        ("README.md", 4, False, True), ("docs/t.md", 1, True, False), ("docs/t.md", 5, True, False)]
    results = [cd.run(c, tmp_path) for c in checks]
    assert results[0] is None and results[3] is None and results[4] is None
    assert "the command gives\n42" in results[1]
    assert "not in the text before it" in results[2]
    assert "the docs say\n| a |\n| 1 |\nthe command gives\n| a |\n| 2 |" == results[5]


def test_a_json_key_of_a_command_is_checked_and_the_command_runs_once(tmp_path):
    cd = _module()
    (tmp_path / "docs").mkdir()
    # the command appends to runs.txt (in the folder it runs in) each time it runs
    command = ('python -c "import json; open(\'runs.txt\', \'a\').write(\'x\'); '
               'print(json.dumps({\'e\': {\'rms\': 9.2214}})); print(\'done\')"')
    (tmp_path / "README.md").write_text(f"RMS 9.22 <!-- check: {command} | e.rms:.2f -> 9.22 -->\n"
                                        f"stale 9.3 <!-- check: {command} | e.rms:.1f -> 9.3 -->; missing 1 <!-- check: {command} | e.max:g -> 1 -->\n")
    first, stale, missing = cd.find_checks(tmp_path)
    assert cd.run(first, tmp_path) is None
    assert "the command gives\n9.2" in cd.run(stale, tmp_path)
    assert "KeyError" in cd.run(missing, tmp_path)
    assert (tmp_path / "runs.txt").read_text() == "x"  # three markers, one run


def test_count_tests_counts_collected_items():
    assert _module().count_tests("tests/test_check_docs.py") == "3 tests"
