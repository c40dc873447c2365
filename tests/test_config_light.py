"""Loading a configuration imports no simulator: config dataclasses live in light modules."""

import subprocess
import sys


def test_loading_a_scenario_config_imports_no_simulator(tmp_path):
    path = tmp_path / "scenario.toml"
    path.write_text('[control]\nmode = "open"\n[model]\ntimestep = 0.002\n[scene.tools]\nspindle_speed = 900.0\n')
    code = (
        "import sys\n"
        "from continuum_sim.scenario.config import ScenarioConfig\n"
        f"assert ScenarioConfig.from_toml({str(path)!r}).control.mode == 'open'\n"
        "print(' '.join(m for m in ('mujoco', 'dm_control', 'scipy') if m in sys.modules))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "", f"imported: {result.stdout.strip()}"
