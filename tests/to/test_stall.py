"""Stall acceptance of a final stage (solver._Run.sink): best feasible iterate flat -> stop with it, otherwise go on."""
import time
from types import SimpleNamespace

import numpy as np

from lomanip_to import solver
from lomanip_to.problem import Options


def _sink(stall=True, **kw):
    prob = SimpleNamespace(options=Options(stall_iterations=5, **kw))
    run = solver._Run(prob, None, t_start=time.perf_counter())
    lbg, ubg = np.zeros(2), np.zeros(2)
    return run, run.sink("final", lbg, ubg, stall=stall)


def _feed(fn, values):
    """values: (objective, violation) per iteration; returns the iteration index that stopped (or None)."""
    for i, (f, v) in enumerate(values):
        if fn(f, np.array([v, 0.0])):
            return i
    return None


def test_feasible_flat_objective_stops_after_the_window():
    run, fn = _sink()
    stop = _feed(fn, [(100.0 - 0.01 * i, 1e-6) for i in range(20)])
    assert stop == 5 and run.stalled
    assert solver._converged(solver.STALLED_STATUS)


def test_progressing_objective_does_not_stop():
    run, fn = _sink()
    assert _feed(fn, [(100.0 * 0.9 ** i, 1e-6) for i in range(20)]) is None
    assert not run.stalled


def test_oscillating_violation_stops_and_keeps_the_best_feasible_iterate():
    """ipopt's violation jumping above constr_tol (S1's carry: 1e-4 .. 5e-3) no longer prevents the
    stop; the stage hands back the best feasible iterate, not the last one."""
    run, fn = _sink()
    stop = None
    for i in range(20):
        f, v = 50.0 - 0.001 * i, (5e-3 if i % 2 else 1e-6)
        if fn(f, np.array([v, 0.0]), lambda i=i: (np.full(3, float(i)), np.zeros(3), np.zeros(2))):
            stop = i
            break
    assert stop == 5 and run.stalled
    f_best, x_best, _, _ = run.best
    assert x_best[0] == 4.0 and f_best == 50.0 - 0.004  # the last feasible iterate was the best


def test_feasible_progress_after_a_late_first_feasible_iterate_does_not_stop():
    run, fn = _sink()
    vals = [(60.0, 1e-2)] * 8 + [(50.0 - i, 1e-6) for i in range(12)]
    assert _feed(fn, vals) is None  # feasible since iteration 8, objective still falling by 1 per iteration


def test_never_feasible_never_stops():
    run, fn = _sink()
    assert _feed(fn, [(50.0, 5e-4)] * 20) is None  # never within constr_tol (1e-4)
    assert run.best is None


def test_guide_stages_and_switched_off_never_stall():
    _, fn = _sink(stall=False)
    assert _feed(fn, [(50.0, 0.0)] * 20) is None
    _, fn = _sink(stall_rtol=0.0)  # any improvement of the best feasible iterate keeps it going
    assert _feed(fn, [(50.0 - 1e-6 * i, 0.0) for i in range(20)]) is None
    prob = SimpleNamespace(options=Options(stall_iterations=0))
    fn = solver._Run(prob, None, time.perf_counter()).sink("final", np.zeros(1), np.zeros(1), stall=True)
    assert _feed(fn, [(50.0, 0.0)] * 20) is None


def test_nearly_feasible_iterates_well_below_the_best_feasible_one_keep_it_going():
    """The demo push of session 25: after one feasible iterate (objective 884) ipopt's iterates sat at
    violations of 1e-3 (above constr_tol) while their objective fell to 58; the stage must go on."""
    run, fn = _sink()
    vals = [(884.0, 1e-6)] + [(884.0 * 0.8 ** (i + 1), 2e-3) for i in range(12)]
    assert _feed(fn, vals) is None and not run.stalled


def test_far_infeasible_low_objectives_do_not_count_as_progress():
    run, fn = _sink()
    vals = [(884.0, 1e-6)] + [(10.0, 0.5)] * 12  # violation 5000 x constr_tol: not nearly feasible
    assert _feed(fn, vals) == 5 and run.stalled


def _capped(case: str, g1, **options):
    from dataclasses import replace

    from lomanip_to.fixtures import load_problem

    prob = load_problem(case, model=g1)
    return solver.solve(replace(prob, options=replace(prob.options, max_iterations=3, **options)), g1)


def test_a_feasible_iterate_at_the_iteration_cap_is_returned_as_such(g1):
    """Standing still is feasible from its first iterates: at a 3-iteration cap the final stage hands
    back its best feasible iterate, named as capped, not as optimal; switched off, the cap fails."""
    res = _capped("case_stand", g1)
    assert res.stats.converged and res.stats.status == solver.CAPPED_FEASIBLE_STATUS
    assert res.stats.max_constraint_violation.value <= res.data.prob.options.constr_tol
    assert "iteration cap" in res.stats.status_message()
    off = _capped("case_stand", g1, accept_feasible_at_cap=False)
    assert not off.stats.converged and off.stats.status == "Maximum_Iterations_Exceeded"


def test_an_infeasible_iterate_at_the_iteration_cap_still_fails(g1):
    res = _capped("case_one_step", g1)   # a step is not feasible after 3 iterations
    assert not res.stats.converged and not res.success
    assert res.stats.status == "Maximum_Iterations_Exceeded"


def _status(ipopt_status, last_stage=True, stalled=False, feasible_best=True, timed_out=False, **options):
    return solver.stage_status(ipopt_status, Options(**options), last_stage=last_stage, stalled=stalled,
                               feasible_best=feasible_best, timed_out=timed_out)


def test_an_early_ipopt_stop_after_a_feasible_iterate_keeps_that_iterate():
    """S2 5.0 kg at yaw 0.6: ipopt ended the pick 'Infeasible_Problem_Detected' on a point within 5e-6
    of every row; with a feasible iterate behind it the final stage counts as converged on it."""
    for st in solver.STOPPED_EARLY_STATUSES:
        out = _status(st)
        assert out == solver.FEASIBLE_BEFORE_STOP_STATUS and solver._converged(out)
        assert _status(st, accept_feasible_at_solver_stop=False) == st
        assert not solver._converged(st)


def test_early_stops_fail_without_a_feasible_iterate_in_a_guide_or_past_the_time_limit():
    st = "Infeasible_Problem_Detected"
    assert _status(st, feasible_best=False) == st
    assert _status(st, last_stage=False) == st   # a guide stage never returns a best iterate
    assert _status(st, timed_out=True) == st
    assert _status("Invalid_Number_Detected") == "Invalid_Number_Detected"  # not an early stop we trust
    assert _status("Solve_Succeeded") == "Solve_Succeeded"


def test_stall_and_cap_statuses_are_unchanged():
    assert _status("User_Requested_Stop", stalled=True) == solver.STALLED_STATUS
    assert _status("Maximum_Iterations_Exceeded") == solver.CAPPED_FEASIBLE_STATUS
    assert _status("Maximum_Iterations_Exceeded", accept_feasible_at_cap=False) == "Maximum_Iterations_Exceeded"


def test_the_message_names_an_early_stop():
    from lomanip_to.result import SolverStats

    msg = SolverStats(converged=True, status=solver.FEASIBLE_BEFORE_STOP_STATUS).status_message()
    assert "before ipopt stopped early" in msg
