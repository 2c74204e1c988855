"""Options.upper_body_speed_limit: bounds on the waist and arm joint speeds at every knot."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem

UPPER = slice(18, 35)  # waist and arm joint speeds (xd indices)
LEGS = slice(6, 18)


def test_bounds_only_on_the_upper_body(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(upper_body_speed_limit=2.5)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw = data.fill(win, *solver.homotopy_stages(prob.options)[-1])[:2]
    xd = win.W["xd"]
    inner = slice(1, data.grid.K - 1)  # the first and last knots are at rest
    assert np.allclose(ubw[xd][UPPER, inner], 2.5) and np.allclose(lbw[xd][UPPER, inner], -2.5)
    assert np.all(ubw[xd][LEGS, inner] == g1.vel_max[:12, None])


def test_one_step_holds_the_limit(g1):
    prob = load_problem("case_one_step", model=g1)
    free = solver.solve(prob, g1)
    limit = 0.5 * np.abs(free.xd_knots[:, UPPER]).max()
    prob.options = prob.options.replaced(upper_body_speed_limit=limit)
    held = solver.solve(prob, g1)
    assert held.stats.converged
    assert np.abs(held.xd_knots[:, UPPER]).max() <= limit + 1e-6
