"""Metrics against a stored reference: outcome leaves exactly, continuous leaves within their tolerance."""

import json
from pathlib import Path

from continuum_sim.scenario.metric_compare import flatten, mismatches

DATA = Path(__file__).parent / "data"


def test_flatten_names_every_leaf_and_list_length():
    leaves = flatten({"a": {"b": [1.5, 2.5]}, "ok": True, "wall_seconds": 3.0, "none": None})
    assert leaves == {"a.b#len": 2, "a.b[0]": 1.5, "a.b[1]": 2.5, "none": None, "ok": True}


def test_a_drift_within_tolerance_passes_and_one_beyond_fails():
    reference = {"error": {"mean": 0.06050770}, "cells": 0, "done": True, "failure": None}
    atol = {"error.mean": 1.6e-5}
    assert mismatches({**reference, "error": {"mean": 0.06050932}}, reference, atol) == []
    [line] = mismatches({**reference, "error": {"mean": 0.0606}}, reference, atol)
    assert line.startswith("error.mean: 0.0606 vs reference 0.0605077")
    assert mismatches({**reference, "error": {"mean": float("nan")}}, reference, atol)
    # Outcomes are never within a tolerance: a flipped flag, another count, a failure named.
    assert mismatches({**reference, "done": False}, reference, atol) == ["done: False vs reference True (outcome: must be equal)"]
    assert mismatches({**reference, "cells": 1}, reference, atol)
    assert mismatches({**reference, "failure": "blocked"}, reference, atol)
    assert mismatches({**reference, "cells": 0.0}, reference, atol)  # a float where the reference has an integer
    assert mismatches({k: v for k, v in reference.items() if k != "done"}, reference, atol) == ["done: missing in the run"]
    assert mismatches({**reference, "extra": 1.0}, reference, atol) == ["extra: not in the reference"]


def test_the_stored_tolerances_cover_the_drift_seen_on_another_machine():
    """The drift that made the README's test fail on another machine (issue 23) is inside the tolerance."""
    reference = json.loads((DATA / "reference_metrics.json").read_text())
    stored = json.loads((DATA / "reference_tolerance.json").read_text())
    # the drift seen then: 0.06050932 mm against 0.06050770 mm stored (linear flexures); the same drift
    # applied to today's reference (its default changed on purpose: nonlinear flexures, issue 24)
    drift = 0.06050932 - 0.06050770
    seen = dict(reference, cutting_tip_error_mm=dict(reference["cutting_tip_error_mm"], mean=reference["cutting_tip_error_mm"]["mean"] + drift))
    assert mismatches(seen, reference, stored["atol"]) == []
    # ... and a tolerance is a small fraction of what it bounds (the test still tells a change from drift).
    assert stored["atol"]["cutting_tip_error_mm.mean"] < 0.01 * reference["cutting_tip_error_mm"]["mean"]
