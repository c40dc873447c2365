"""The named outcome of a run (``scenario.metrics.task_outcome``): each failure is recognised,
the first that applies wins, and a complete task has none."""

import pytest

from continuum_sim.scenario.metrics import TASK_FAILURES, task_outcome

RATING = 200.0


def _metrics(**changes):
    base = {"max_cable_tension_n": 120.0, "cutting": {"stall_events": 0}, "detached_before_cut_complete": False,
            "sample_detached": True, "sample_held_at_end": True}
    return base | changes


@pytest.mark.parametrize(
    "changes, all_stages, failure",
    [
        ({}, True, None),
        ({"diverged": "simulation diverged: non-finite state"}, True, "diverged"),
        ({}, False, "partial_run"),
        ({"detached_before_cut_complete": True, "sample_held_at_end": False}, True, "detached_early"),
        ({"sample_detached": False, "max_cable_tension_n": 200.0, "cutting": {"stall_events": 2}}, True, "cables_saturated"),
        ({"sample_detached": False, "cutting": {"stall_events": 1}}, True, "spindle_stalled"),
        ({"sample_detached": False}, True, "cut_incomplete"),
        ({"sample_held_at_end": False}, True, "sample_dropped"),
    ],
)
def test_each_failure_is_named_and_the_first_wins(changes, all_stages, failure):
    outcome = task_outcome(_metrics(**changes), all_stages, RATING)
    assert outcome["failure"] == failure
    assert outcome["completed"] is (failure is None)
    assert failure is None or failure in TASK_FAILURES


def test_saturation_is_reported_even_when_the_task_completes():
    outcome = task_outcome(_metrics(max_cable_tension_n=199.0), True, RATING)
    assert outcome == {"completed": True, "failure": None, "cables_saturated": True}

