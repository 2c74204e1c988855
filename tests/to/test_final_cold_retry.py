"""A final stage that started warm and failed is solved again from its guide's point, cold
(``Options.final_cold_retry``)."""
from dataclasses import replace

import pytest

from lomanip_to import solver
from lomanip_to.fixtures import load_problem


def _lift_box(g1):
    """case_lift_box with the lighter sole-load-rate cost whose final stage starts warm
    (tests/to/test_warm_start_guard.py)."""
    prob = load_problem("case_lift_box", model=g1)
    return replace(prob, options=replace(prob.options, weights={**(prob.options.weights or {}), "w_force_rate": 10.0}))


@pytest.fixture
def first_warm_final_fails(monkeypatch):
    """Injected failure: the first final stage ends 'Maximum_Iterations_Exceeded' whatever ipopt
    did (case_lift_box's warm final converges in 8 iterations; no small case fails warm on its own)."""
    real = solver.stage_status
    calls = {"final": 0}

    def status(ipopt_status, opt, last_stage, **kw):
        if last_stage:
            calls["final"] += 1
            if calls["final"] == 1:
                return "Maximum_Iterations_Exceeded"
        return real(ipopt_status, opt, last_stage=last_stage, **kw)

    monkeypatch.setattr(solver, "stage_status", status)
    return calls


def test_a_failed_warm_final_is_retried_cold(g1, first_warm_final_fails):
    prob = _lift_box(g1)
    res = solver.solve(replace(prob, options=replace(prob.options, final_cold_retry=True)), g1)
    names = [st["stage"] for st in res.stats.stages]
    assert names[-2:] == ["final", "cold retry final"], names
    assert res.stats.stages[-2]["start"] == "warm" and res.stats.stages[-1]["start"] == "cold"
    assert res.stats.converged, res.stats.status_message()
    # the retry's iterations count in the solve (the progress count includes each stage's start point)
    assert res.stats.iterations == sum(st["iterations"] + 1 for st in res.stats.stages)


def test_without_the_option_the_failure_stands(g1, first_warm_final_fails):
    res = solver.solve(_lift_box(g1), g1)
    assert [st["stage"] for st in res.stats.stages][-1] == "final"
    assert not res.stats.converged
