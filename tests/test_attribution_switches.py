"""The attribution switches (docs/calibration.md): `model.gravity`, `scene.gripper_plate_contact`.

Each is validated like every field (one line, exit 2) and does what it says in the compiled
model: no gravity; no contact between the gripper's bodies and the fixed plate, while the
sample (what the jaws grasp) still collides with them.
"""

import dataclasses
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from continuum_sim.model.scene import PLATE_BODY, SAMPLE_BODY
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import build_scene_model


@pytest.mark.parametrize(
    "toml_text, field",
    [("[model]\ngravity = \"off\"\n", "gravity"), ("[scene]\ngripper_plate_contact = 1\n", "gripper_plate_contact")],
)
def test_bad_switch_is_one_line_and_exit_2(tmp_path, toml_text, field):
    path = tmp_path / "bad.toml"
    path.write_text(toml_text)
    out = tmp_path / "run"
    result = subprocess.run([sys.executable, "-m", "continuum_sim", "run", "--config", str(path), "--out", str(out)],
                            capture_output=True, text=True, env={**__import__("os").environ, "MUJOCO_GL": "disable"})
    assert result.returncode == 2, result.stderr
    assert f"{field}: must be true or false" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not out.exists()


def _compiled(model_changes=None, scene_changes=None) -> mujoco.MjModel:
    c = ScenarioConfig.default()
    c = dataclasses.replace(c, model=dataclasses.replace(c.model, **(model_changes or {})),
                            scene=dataclasses.replace(c.scene, **(scene_changes or {})))
    return build_scene_model(c)[1]


def _excluded_pairs(m: mujoco.MjModel) -> set[tuple[str, str]]:
    pairs = set()
    for sig in m.exclude_signature:
        b1, b2 = int(sig) >> 16, int(sig) & 0xFFFF
        pairs.add(tuple(sorted((m.body(b1).name, m.body(b2).name))))
    return pairs


def test_switches_change_the_compiled_model():
    base = _compiled()
    assert np.allclose(base.opt.gravity, (0, 0, -9.81)) and base.nexclude == 0
    m = _compiled({"gravity": False}, {"gripper_plate_contact": False})
    assert np.all(m.opt.gravity == 0.0)
    pairs = _excluded_pairs(m)
    gripper_bodies = {m.body(int(b)).name for b in set(m.geom_bodyid) if "/gripper/" in m.body(int(b)).name}
    assert {"right/gripper/palm", "right/gripper/jaw_a", "right/gripper/jaw_b"} <= gripper_bodies
    assert pairs >= {tuple(sorted((b, PLATE_BODY))) for b in gripper_bodies}
    assert not any(SAMPLE_BODY in p for p in pairs)  # the jaws still grasp the sample
