"""Stall acceptance of a final stage (solver._Run.sink): feasible and flat -> stop, otherwise go on."""
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


def test_infeasible_iterate_in_the_window_does_not_stop():
    run, fn = _sink()
    vals = [(50.0, 1e-6)] * 20
    vals[3] = (50.0, 5e-3)  # above stall_constr_tol: the window restarts after it
    assert _feed(fn, vals) == 9


def test_current_iterate_must_meet_constr_tol():
    run, fn = _sink()
    assert _feed(fn, [(50.0, 5e-4)] * 20) is None  # within stall_constr_tol, never within constr_tol


def test_guide_stages_and_switched_off_never_stall():
    _, fn = _sink(stall=False)
    assert _feed(fn, [(50.0, 0.0)] * 20) is None
    _, fn = _sink(stall_rtol=0.0)
    assert _feed(fn, [(50.0 + 1e-3 * i, 0.0) for i in range(20)]) is None
    prob = SimpleNamespace(options=Options(stall_iterations=0))
    fn = solver._Run(prob, None, time.perf_counter()).sink("final", np.zeros(1), np.zeros(1), stall=True)
    assert _feed(fn, [(50.0, 0.0)] * 20) is None
