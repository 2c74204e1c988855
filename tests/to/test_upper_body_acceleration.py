"""Options.upper_body_acceleration_limit: rows on the base rotation, waist and arm accelerations."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem

UPPER = list(range(3, 6)) + list(range(18, 35))  # base rotation rates, waist, arms (x indices)


def _upper_acceleration(res):
    """max over interior knots of |xd_k+1 - xd_k| / (t_k+1 - t_k) on the upper body (rad/s^2)."""
    dv = np.diff(res.xd_knots, axis=0) / np.diff(res.t_knots)[:, None]
    return np.abs(dv[:-1][:, UPPER]).max()


def test_rows_exist_only_when_asked(g1):
    prob = load_problem("case_one_step", model=g1)
    assert not ProblemData(prob, g1).structure.upper_body_acceleration
    prob.options = prob.options.replaced(upper_body_acceleration_limit=10.0)
    assert ProblemData(prob, g1).structure.upper_body_acceleration


def test_one_step_holds_the_limit(g1):
    prob = load_problem("case_one_step", model=g1)
    free = solver.solve(prob, g1)
    prob.options = prob.options.replaced(upper_body_acceleration_limit=5.0)
    held = solver.solve(prob, g1)
    assert held.stats.converged
    assert _upper_acceleration(held) <= 5.0 + 1e-3
    assert _upper_acceleration(free) > 5.0  # so the rows did something
