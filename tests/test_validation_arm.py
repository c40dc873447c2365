"""The arm's own figures against independent references: tendon statics (Cosserat) and modes (beam).

Quick subsets; the full sweeps are rows of `continuum-sim validate` (docs/validation.md).
"""

import math

import numpy as np
import pytest

from continuum_sim.geometry import ArmGeometry
from continuum_sim.model.options import ModelOptions
from continuum_sim.validation.modes import beam_frequencies, compare_section_modes
from continuum_sim.validation.tendon_arm import (
    ArmStatics,
    compare,
    max_single_tension,
    section_geometry,
)

GEOMETRY = ArmGeometry.default()
OPTIONS = ModelOptions(joint="hinge_pair")


def test_distal_section_bends_like_the_cosserat_model():
    """One cable at a quarter of the 90° tension, gravity sideways, and a two-cable pair:
    tip within 1 % of the section length, bend per unit tension within 5 %."""
    geo = section_geometry(GEOMETRY, (2,))
    statics = ArmStatics(geo, OPTIONS)
    t = max_single_tension(GEOMETRY, 2, OPTIONS)
    for tensions, gravity in (([0.25 * t, 0, 0], (-9.81, 0, 0)), ([0.15 * t, 0.1 * t, 0], (0, 0, -9.81))):
        c = compare(statics, np.array(tensions), gravity)
        assert c.converged
        assert c.tip_error_pct <= 1.0
        assert abs(c.bend_error_pct) <= 5.0


def test_the_gap_to_cosserat_is_the_disks_chord_effect():
    """At a 45° bend the disk chain bends more than the continuum (the cable's straight
    chord between holes passes farther from the joint than r); the excess shrinks ~1/n²:
    about 4× from 10 to 20 joints per section."""
    t = 0.5 * max_single_tension(GEOMETRY, 2, OPTIONS)
    excess = []
    for n in (10, 20):
        options = ModelOptions(joint="hinge_pair", segments_per_section=n)
        c = compare(ArmStatics(section_geometry(GEOMETRY, (2,)), options), np.array([t, 0, 0]), (0, 0, 0))
        excess.append(c.bend_error_pct)
    assert excess[0] > 0 and excess[1] > 0
    assert 3.0 < excess[0] / excess[1] < 5.0


def test_beam_reference_reproduces_published_cantilever_roots():
    """β₁L = 1.8751, β₂L = 4.6941 (clamped-free); a tip mass equal to the beam's lowers β₁L to 1.2479."""
    f = beam_frequencies(1.0, 1.0, 1.0, count=2)
    assert np.sqrt(2 * math.pi * f) == pytest.approx([1.8751, 4.6941], abs=2e-4)
    f = beam_frequencies(1.0, 1.0, 1.0, tip_mass=1.0, count=1)
    assert math.sqrt(2 * math.pi * f[0]) == pytest.approx(1.2479, abs=2e-4)


def test_cable_held_distal_section_first_mode_matches_the_beam():
    """mjd_transitionFD of the held, undamped section: 1st bending pair within 5 % of the
    Rayleigh beam with the ropes' rotational spring; the ropes stiffen it (f above cables-off)."""
    held = compare_section_modes(GEOMETRY, 2, OPTIONS, count=1)
    free = compare_section_modes(GEOMETRY, 2, ModelOptions(joint="hinge_pair", tendons=False), count=1)
    assert abs(held.errors_pct()[0]) <= 5.0
    assert held.model[0] > free.model[0]
    assert held.reference[0] > free.reference[0]
