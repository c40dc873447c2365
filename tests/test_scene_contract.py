"""The scene contract (model.handles): ids resolved from the builders' names, nowhere else."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from continuum_sim.layout import ARMS
from continuum_sim.model.handles import GeomKind, SceneHandles
from continuum_sim.model.options import model_geometry
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.scenario.runner import build_scene_model

PACKAGE = Path(__file__).resolve().parent.parent / "continuum_sim"


@pytest.fixture(scope="module")
def scene():
    config = ScenarioConfig.default()
    _, model = build_scene_model(config)
    return config, model, SceneHandles.from_model(model, model_geometry(config.arm, config.model), config.layout)


def _element_names(model: mujoco.MjModel) -> set[str]:
    kinds = [
        (model.nbody, mujoco.mjtObj.mjOBJ_BODY), (model.ngeom, mujoco.mjtObj.mjOBJ_GEOM),
        (model.nsite, mujoco.mjtObj.mjOBJ_SITE), (model.njnt, mujoco.mjtObj.mjOBJ_JOINT),
        (model.ntendon, mujoco.mjtObj.mjOBJ_TENDON), (model.nu, mujoco.mjtObj.mjOBJ_ACTUATOR),
        (model.neq, mujoco.mjtObj.mjOBJ_EQUALITY),
    ]
    out = set()
    for n, kind in kinds:
        out.update(mujoco.mj_id2name(model, kind, i) or "" for i in range(n))
    return out - {""}


# Scoped names and the builders' per-arm patterns; a literal containing one is a model name.
SCOPED = re.compile(r"/(cable_|disk_|joint_|hole_|tcp$|tool_mount|grinder/|gripper/)|^(cable|disk|joint|hole)_\d")


def test_no_model_name_literal_outside_the_model_package(scene):
    """Every string constant outside continuum_sim/model/ is checked against the scene's names."""
    _, model, _ = scene
    # Scoped names (the arms' and tools') and the weld; bare words that are also element
    # names ("plate", "tcp", "cutter") are too common in labels and keys to police by value.
    robot_names = {n for n in _element_names(model) if "/" in n or n == "sample_weld"}
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if "model" in path.relative_to(PACKAGE).parts[:1]:
            continue
        tree = ast.parse(path.read_text())
        docstrings = {
            id(node.body[0].value)
            for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef))
            and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
                text = node.value
                if text in robot_names or (SCOPED.search(text) and " " not in text):
                    offenders.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}: {text!r}")
    assert not offenders, "model names outside continuum_sim/model/ (use model.handles / model.names):\n" + "\n".join(offenders)


def test_handles_resolve_every_id_the_runtime_needs(scene):
    config, model, h = scene
    geometry = model_geometry(config.arm, config.model)
    assert h.arms == ARMS
    assert h.grinder_arm == config.layout.arm_for("grinder") and h.gripper_arm == config.layout.arm_for("gripper")
    for arm in ARMS:
        assert len(h.cable_actuators[arm]) == len(h.cable_tendons[arm]) == 3 * geometry.n_sections
        # each cable actuator drives the tendon of the same index
        np.testing.assert_array_equal(model.actuator_trnid[h.cable_actuators[arm], 0], h.cable_tendons[arm])
        assert len(h.disk_bodies[arm]) == sum(s.n_segments for s in geometry.sections)
        assert model.site_bodyid[h.tcp_site[arm]] == h.disk_bodies[arm][-1]
    assert model.actuator_trntype[h.spindle_actuator] == mujoco.mjtTrn.mjTRN_JOINT
    assert model.eq_type[h.sample_weld] == mujoco.mjtEq.mjEQ_WELD
    assert model.geom_contype[h.cutter_geom] == 0 and model.geom_conaffinity[h.cutter_geom] == 0  # it cuts voxels
    kinds = h.geom_kind
    assert np.count_nonzero(kinds == GeomKind.CUTTER) == 1 and kinds[h.cutter_geom] == GeomKind.CUTTER
    assert np.count_nonzero(kinds == GeomKind.GRIPPER) >= 3  # palm, jaws, pads
    for arm in ARMS:
        own = kinds[np.isin(model.geom_bodyid, h.disk_bodies[arm])]
        assert np.all(own == GeomKind.of_arm(arm))
