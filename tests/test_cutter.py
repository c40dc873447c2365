"""The compiled cutter (plant/cutter_kernels.py) against a vectorised numpy oracle of its
engagement, its public-API fallback against its raw-address path, and one writer of the
spindle's ctrl."""

import math

import mujoco
import numpy as np
import pytest
from test_cutting import OFFSET, SPEED, cut_path, make, step

from continuum_sim.plant import cutter_kernels as ck


def _oracle(material, lo, h, cx, cy, z0, z1, r, probe, probe2, recent, ex, ey, probes):
    """numpy: (voxels inside the cutter, Σ a·I_cc, Σ a·I_cs, Σ a·I_c, mean a), written from the
    model's description (voxel centres in the cylinder; a = material depth in the probe's
    column within [z0, z1]; 0 where a recent centre's probe circle holds the probe)."""
    centres = [lo[a] + (np.arange(n) + 0.5) * h[a] for a, n in enumerate(material.shape)]
    x, y, z = np.meshgrid(*centres, indexing="ij")
    n_inside = int(np.count_nonzero(material & ((x - cx) ** 2 + (y - cy) ** 2 <= r * r) & (z >= z0) & (z <= z1)))
    edges = lo[2] + np.arange(material.shape[2] + 1) * h[2]
    weights = np.clip(np.minimum(edges[1:], z1) - np.maximum(edges[:-1], z0), 0.0, None)
    cos_t, sin_t, i_cc, i_cs, i_c = probes
    qx = cx + probe * (ex * cos_t - ey * sin_t)
    qy = cy + probe * (ey * cos_t + ex * sin_t)
    i = np.floor((qx - lo[0]) / h[0]).astype(int)
    j = np.floor((qy - lo[1]) / h[1]).astype(int)
    ok = (i >= 0) & (i < material.shape[0]) & (j >= 0) & (j < material.shape[1])
    depth = np.zeros(len(qx))
    depth[ok] = material[i[ok], j[ok], :] @ weights
    reached = (((qx[:, None] - recent[None, :, 0]) ** 2 + (qy[:, None] - recent[None, :, 1]) ** 2) < probe2).any(axis=1)
    depth[reached] = 0.0
    return n_inside, depth @ i_cc, depth @ i_cs, depth @ i_c, depth.mean()


def test_engagement_equals_the_numpy_oracle_on_random_cuts():
    """``inside`` and ``engage`` on random partly cut grids, cutter positions, feed directions and
    recent centres: the same count, the depth sums within 1e-12 relative (summation order only)."""
    rng = np.random.default_rng(3)
    _, _, cutter = make()
    probes = cutter._probes
    checked = 0
    for _ in range(200):
        shape = tuple(int(n) for n in rng.integers(4, 30, size=3))
        material = rng.random(shape) < rng.uniform(0.3, 1.0)
        lo, h = rng.normal(0.0, 0.01, 3), rng.uniform(5e-4, 2e-3, 3)
        r = rng.uniform(1.5, 5.0) * h[0]
        probe = r + h[:2].max()
        cx, cy = lo[:2] + rng.uniform(-0.1, 1.1, 2) * np.array(shape[:2]) * h[:2]
        z0, z1 = np.sort(lo[2] + rng.uniform(-0.2, 1.2, 2) * shape[2] * h[2])
        angle = rng.uniform(0, 2 * math.pi)
        ex, ey = math.cos(angle), math.sin(angle)
        recent = np.full((8, 2), np.inf)
        recent[:3] = np.array([cx, cy]) - rng.uniform(0, 2 * probe, (3, 1)) * np.array([ex, ey])
        state = np.zeros(1, ck.CUTTER)
        s = state[0]
        s["lo"], s["h"], s["cx"], s["cy"], s["z0"], s["z1"] = lo, h, cx, cy, z0, z1
        s["ex"], s["ey"], s["probe"], s["probe2"] = ex, ey, probe, (probe - 1e-9) ** 2
        n_inside, _, _ = ck.inside(material, material, material[:, :, 0].astype(np.float32), lo, h, cx, cy, z0, z1, r,
                                   False, 0.0)
        mean = ck.engage(material, recent, probes, state[0])
        want = _oracle(material, lo, h, cx, cy, z0, z1, r, probe, (probe - 1e-9) ** 2, recent, ex, ey, probes)
        assert n_inside == want[0]
        got = (float(state["d_cc"][0]), float(state["d_cs"][0]), float(state["d_c"][0]), mean)
        np.testing.assert_allclose(got, want[1:], rtol=1e-12, atol=1e-18)
        checked += n_inside > 0 and want[3] > 0
    assert checked > 20


def test_public_api_fallback_equals_the_raw_address_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The kernels call mj_jac/mj_solveM by address; where MuJoCo's library is not found next to
    the bindings (``jit.mujoco_symbols`` None) the cutter calls MuJoCo's public API between
    ``begin`` and ``finish``. Along the L cut (feeding, removal, the recent-centres exclusion)
    both give the same state within 1e-12 (the same C functions: in practice bit for bit)."""
    from continuum_sim.plant import mujoco_native as jit

    native = make()
    monkeypatch.setattr(jit, "mujoco_symbols", lambda *names: None)
    fallback = make()
    assert native[2].native and not fallback[2].native
    points = cut_path()
    feeding = 0
    for model, data, _ in (native, fallback):
        free = model.jnt_qposadr[model.body("left/").jntadr[0]]
        data.mocap_pos[model.body("left_target").mocapid[0]] = data.qpos[free:free + 3] = points[0] - OFFSET
        mujoco.mj_forward(model, data)
    direction = (points[1] - points[0]) / np.linalg.norm(points[1] - points[0])
    while native[1].time < 0.9:
        states = []
        for model, data, cutter in (native, fallback):
            s = 0.04 * max(data.time - 0.5, 0.0) + 0.0008 * math.sin(2 * math.pi * 7.0 * data.time)
            data.mocap_pos[model.body("left_target").mocapid[0]] = points[0] + s * direction - OFFSET
            states.append(step(model, data, cutter, SPEED))
        feeding += bool(native[2].record["feeding"][0])
        np.testing.assert_allclose(native[1].qvel, fallback[1].qvel, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose([states[0].feed_force, states[0].torque], [states[1].feed_force, states[1].torque],
                                   rtol=1e-12, atol=1e-15)
    assert feeding > 50 and native[2].removed_volume > 0
    assert native[2].removed_volume == pytest.approx(fallback[2].removed_volume, rel=1e-12)
    assert np.array_equal(native[2].grid.material, fallback[2].grid.material)


def test_the_cutter_does_not_write_the_spindle_ctrl():
    """One writer per actuator: the spindle drive sets the spindle's ctrl; the cutter only
    loads the spindle joint (qfrc_applied)."""
    model, data, cutter = make()
    data.ctrl[cutter.spindle.actuator] = 123.0
    for _ in range(20):
        cutter.step()
        mujoco.mj_step(model, data)
    assert data.ctrl[cutter.spindle.actuator] == 123.0
