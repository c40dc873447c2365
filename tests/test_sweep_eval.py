"""Static sweep evaluations: the physics they show, determinism, shared-model identity."""

import numpy as np
import pytest

from continuum_sim.configio import replace_path
from continuum_sim.scenario.config import ScenarioConfig
from continuum_sim.sweep import GravitySag, TipDeflection
from continuum_sim.sweep.static import (
    build_model,
    evaluate_static,
    evaluate_static_shared,
    model_bytes,
    patch_model,
    structure_key,
)

BASE = ScenarioConfig.default()
# x16 around the shipped segments, within the motors' rating (at x4 a cable goes slack, at x8 they saturate)
SCALES = (0.125, 0.25, 0.5, 1.0, 2.0)


def variant(**paths):
    config = BASE
    for path, value in paths.items():
        config = replace_path(config, path.replace("__", "."), value)
    return config


def shared(configs, evaluation, nthread=2):
    results = [None] * len(configs)
    for indices, part in evaluate_static_shared(configs, evaluation, nthread=nthread, chunk=3):
        for i, r in zip(indices, part):
            results[i] = r
    return results


def test_gravity_sag_falls_as_hinge_stiffness_rises():
    """Cables fix each section's total bend; the hinges resist gravity's non-uniform part."""
    configs = [variant(model__stiffness_scale=s) for s in SCALES]
    results = shared(configs, GravitySag(settle_s=1.5))
    sag = np.array([r["sag_mm"] for r in results])
    assert np.all(np.diff(sag) < 0), sag
    assert sag[0] > 3 * sag[-1]  # a 16x stiffer arm sags several times less
    assert sag[SCALES.index(1.0)] > 5.0  # the nominal open-loop arm sags visibly (cf. test_control)
    assert all(r["residual_speed_rad_s"] < 1e-2 for r in results)  # settled: a static answer
    # stiffer hinges need more cable tension to hold the same bend
    tension = np.array([r["max_cable_tension_n"] for r in results])
    assert np.all(np.diff(tension[1:]) > 0), tension


def test_tip_deflection_of_the_free_backbone_matches_the_linear_spring_chain():
    """No cables, no gravity, small load: deflection = J K⁻¹ Jᵀ F and ∝ 1/stiffness.

    Without a payload (its inertia only slows the settling when gravity is off)."""
    evaluation = TipDeflection(force_n=0.005, settle_s=6.0, tool="none")
    results = shared([variant(model__stiffness_scale=s) for s in (1.0, 2.0)], evaluation)
    for r in results:
        assert r["deflection_along_force_mm"] == pytest.approx(r["linear_prediction_mm"], rel=0.02)
        assert r["payload_kg"] == 0.0
    assert results[0]["deflection_mm"] / results[1]["deflection_mm"] == pytest.approx(2.0, rel=0.03)
    held = evaluate_static(BASE, TipDeflection(force_n=0.005, settle_s=2.0, cables="held"))
    assert held["linear_prediction_mm"] is None and held["max_cable_tension_n"] > 0
    assert held["deflection_mm"] < 0.5 * results[0]["deflection_mm"]  # held cables stiffen the arm


def test_same_variant_gives_bit_identical_metrics():
    config = variant(model__stiffness_scale=2.0)
    evaluation = GravitySag(settle_s=0.3)
    assert evaluate_static(config, evaluation) == evaluate_static(config, evaluation)


def test_shared_model_equals_a_fresh_build_byte_for_byte_and_gives_identical_metrics():
    evaluation = GravitySag(settle_s=0.3)
    configs = [
        variant(model__stiffness_scale=0.7),
        variant(model__stiffness_scale=3.0, model__joint_damping=0.5),
        variant(arm__sections__2__hinge_thickness=0.0012, arm__material__youngs_modulus=3.1e9),
        variant(arm__sections__0__hinge_width=0.007, control__pretension=4.0),
    ]
    keys = {structure_key(c, evaluation) for c in configs}
    assert len(keys) == 1
    base_model = build_model(BASE, evaluation)
    for config in configs:
        assert model_bytes(patch_model(base_model, config, evaluation)) == model_bytes(build_model(config, evaluation))
    # a field that changes the structure must not share a model
    assert structure_key(variant(model__cable_kp=2e4), evaluation) not in keys
    assert structure_key(variant(arm__sections__1__length=0.17), evaluation) not in keys
    per_variant = [evaluate_static(c, evaluation) for c in configs]
    assert shared(configs, evaluation) == per_variant
    assert shared(configs, evaluation, nthread=1) == per_variant


def test_a_diverging_variant_is_a_failure_with_a_reason_not_an_exception():
    evaluation = GravitySag(settle_s=0.2)
    results = shared([variant(model__stiffness_scale=1.0), variant(model__stiffness_scale=300.0)], evaluation)
    assert isinstance(results[0], dict)
    assert isinstance(results[1], Exception) and str(results[1]).startswith("diverged")
