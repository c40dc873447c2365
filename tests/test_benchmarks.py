"""The benchmark scripts run where the project is installed (their figures live in benchmarks/*.json)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_warp_sweep_says_why_and_exits_0_without_a_gpu():
    """On a machine without mujoco-warp or an NVIDIA GPU the GPU benchmark names the reason in one line."""
    try:
        import warp  # noqa: F401

        import mujoco_warp  # noqa: F401

        has_warp = True
    except ImportError:
        has_warp = False
    result = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "warp_sweep.py")], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    if not has_warp:
        assert lines == ["warp_sweep: not run: mujoco-warp is not installed (warp); install the optional extra: pip install -e .[warp]"]
    elif lines[0].startswith("warp_sweep: not run:"):
        assert len(lines) == 1 and ("CUDA" in lines[0] or "GPU" in lines[0])
