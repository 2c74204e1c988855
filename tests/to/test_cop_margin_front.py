"""Options.cop_margin_front: the soles' toe-side force points moved back from the toe edge, so a
planned centre of pressure keeps that distance from the toes."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import FEET, SOLE_CENTER, SOLE_CORNERS, SOLE_FORCE_POINTS, sole_force_points
from lomanip_to.problem import INVALID_REQUEST, ProblemError, validate_problem


def test_default_is_the_model_force_points():
    np.testing.assert_allclose(sole_force_points(), SOLE_FORCE_POINTS)


def test_only_the_toe_side_points_move():
    pts = sole_force_points(0.05)
    toe = SOLE_CORNERS[:, 0] > SOLE_CENTER[0]
    np.testing.assert_allclose(pts[toe, 0], SOLE_CORNERS[toe, 0] - 0.05)
    np.testing.assert_allclose(pts[~toe], SOLE_FORCE_POINTS[~toe])
    np.testing.assert_allclose(pts[:, 1:], SOLE_FORCE_POINTS[:, 1:])


def test_single_stance_com_rows_use_the_moved_points(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(cop_margin_front=0.05, single_support_com_margin=0.0)
    data = ProblemData(prob, g1)
    assert data.structure.cop_margin_front == 0.05
    win, _ = solver.get_window(g1, data.structure)
    _, _, _, ubg, _, _ = data.fill(win, 2.0, True, True, True)
    single = [(k, f) for k in range(data.grid.K) for f in FEET
              if data.contact(k, f) is not None and all(data.contact(k, o) is None for o in FEET if o != f)]
    assert single
    for k, foot in single:
        assert ubg[win.G[f"{foot} CoM over the sole"], k][0] == pytest.approx(SOLE_CORNERS[:, 0].max() - 0.05 - SOLE_CENTER[0])


@pytest.mark.parametrize("name, value", [("cop_margin_front", -0.01), ("cop_margin_front", 0.2),
                                         ("cop_margin_front", float("nan")), ("cop_margin_side", -0.01),
                                         ("cop_margin_side", 0.03), ("cop_margin_side", float("nan"))])
def test_out_of_range_is_refused(g1, name, value):
    """Either sole margin (toe, sides) out of its range is refused before any solve."""
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(**{name: value})
    with pytest.raises(ProblemError) as e:
        validate_problem(prob, g1)
    assert e.value.code == INVALID_REQUEST and name in str(e.value)


def test_one_step_keeps_its_centre_of_pressure_behind_the_toe_points(g1):
    """Solved with the toe-side points 5 cm inside the toe edge (3 cm more than the default), every
    stance foot's planned centre of pressure, from the plan's own foot forces and moments, lies at
    most 7 cm ahead of the ankle (the default allows 10)."""
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(cop_margin_front=0.05)
    res = solver.solve(prob, g1)
    assert res.stats.converged, res.stats.status_message()
    front = SOLE_CORNERS[:, 0].max() - 0.05
    checked = 0
    for k in range(len(res.t_knots)):
        tree = g1.numeric(res.x_knots[k])["tree"]
        for f in FEET:
            F, T, p = res.forces_knots[f][k], res.torques_knots[f][k], res.points_knots[f][k]
            if F[2] < 20.0:
                continue
            cop = p + np.array([-T[1], T[0], 0.0]) / F[2]
            jid = g1.limb_joint[f]
            R, o = np.asarray(tree["R"][jid], float), np.asarray(tree["p"][jid], float).ravel()
            along = (R.T @ (cop - o))[0]
            assert along <= front + 2e-3, (res.t_knots[k], f, along)
            checked += 1
    assert checked > 10
