"""A converged guide warm-starts the final stage only when its point is near the final stage's rows
(``Options.final_warm_start_max_violation``)."""
from lomanip_to import solver
from lomanip_to.fixtures import load_problem


def _final_stage(res):
    return next(st for st in res.stats.stages if st["stage"].endswith("final"))


def _lift_box(g1):
    """case_lift_box with a lighter sole-load-rate cost.  Named: at the default w_force_rate (20)
    this case's guide stops in Restoration_Failed after 70 iterations (the final stage then
    converges from its point, cold, in 51), so the warm path is exercised at 10 (guide converges in
    101 iterations, final warm in 8)."""
    from dataclasses import replace

    prob = load_problem("case_lift_box", model=g1)
    return replace(prob, options=replace(prob.options, weights={**(prob.options.weights or {}), "w_force_rate": 10.0}))


def test_final_stage_is_warm_started_near_and_cold_started_far(g1):
    from dataclasses import replace

    res = solver.solve(_lift_box(g1), g1)
    assert res.success and _final_stage(res)["start"] == "warm"

    # with no tolerated start violation, the same final stage starts from the guide's point cold
    prob = _lift_box(g1)
    cold = solver.solve(replace(prob, options=replace(prob.options, final_warm_start_max_violation=0.0)), g1)
    assert _final_stage(cold)["start"] == "cold"
    assert cold.stats.converged, cold.stats.status_message()


def test_start_violation_is_measured_against_the_stage_bounds(g1):
    import numpy as np

    from lomanip_to.discretize import ProblemData

    prob = load_problem("case_stand", model=g1)
    data = ProblemData(prob, g1)
    win, wd = solver.get_window(g1, data.structure)
    lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *solver.homotopy_stages(prob.options)[-1])
    args = dict(lbx=solver._vec(lbw), ubx=solver._vec(ubw), lbg=solver._vec(lbg), ubg=solver._vec(ubg), p=solver._vec(Pm))
    z = solver._vec(W0)
    v = solver._start_violation(wd, data, data.grid.K, 2, win, z, args, hom=True)
    assert np.isfinite(v) and v >= 0.0
    # tightening every finite row to its value +1 makes the violation at least 1
    nlp = solver.get_nlp(wd, data.structure, data.grid.K, 2)
    g = np.array(nlp.F_nlp(np.clip(z, args["lbx"], args["ubx"]), args["p"])[1]).ravel()
    tight = dict(args, lbg=np.where(np.isfinite(args["lbg"]), g + 1.0, args["lbg"]))
    assert solver._start_violation(wd, data, data.grid.K, 2, win, z, tight, hom=False) >= 1.0 - 1e-9


def test_final_warm_start_bound_is_validated(g1):
    import pytest
    from dataclasses import replace

    from lomanip_to.problem import ProblemError, validate_problem

    prob = load_problem("case_stand", model=g1)
    for bad in (-1.0, float("nan")):
        with pytest.raises(ProblemError, match="final_warm_start_max_violation"):
            validate_problem(replace(prob, options=replace(prob.options, final_warm_start_max_violation=bad)), g1)
