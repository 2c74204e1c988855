"""Options.cop_margin_side: the soles' force points moved in from the sole's sides, so a planned
centre of pressure keeps that distance from a side edge (S1 at 2.5 kg / 1.2 rad rolled over one)."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import FEET, SOLE_CENTER, SOLE_CORNERS, SOLE_FORCE_POINTS, sole_force_points
from lomanip_to.problem import Options


def test_default_keeps_the_model_force_points():
    assert Options().cop_margin_side == 0.01
    np.testing.assert_allclose(sole_force_points(side_margin=0.01), SOLE_FORCE_POINTS)


def test_every_point_moves_in_from_its_side_only():
    pts = sole_force_points(side_margin=0.015)
    side = np.sign(SOLE_CORNERS[:, 1] - SOLE_CENTER[1])
    np.testing.assert_allclose(pts[:, 1], SOLE_CORNERS[:, 1] - side * 0.015)
    np.testing.assert_allclose(pts[:, [0, 2]], SOLE_FORCE_POINTS[:, [0, 2]])
    # with the toe margin as well: each margin moves its own coordinate
    both = sole_force_points(0.04, 0.015)
    np.testing.assert_allclose(both[:, 1], pts[:, 1])
    np.testing.assert_allclose(both[:, 0], sole_force_points(0.04)[:, 0])


def test_double_stance_com_rows_use_the_moved_points(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(cop_margin_side=0.015, double_support_com_margin=0.0)
    data = ProblemData(prob, g1)
    assert data.structure.cop_margin_side == 0.015
    assert data.structure.key() != ProblemData(load_problem("case_one_step", model=g1), g1).structure.key()
    win, _ = solver.get_window(g1, data.structure)
    _, _, _, ubg, _, _ = data.fill(win, 2.0, True, True, True)
    double = [k for k in range(data.grid.K) if all(data.contact(k, f) is not None for f in FEET)]
    assert double
    for k in double:  # across: the force points' extent less the margin (0 here)
        assert ubg[win.G["CoM inside the double stance"], k][3] == pytest.approx(SOLE_CORNERS[:, 1].max() - 0.015)

# out-of-range values: tests/to/test_cop_margin_front.py::test_out_of_range_is_refused (both margins)
