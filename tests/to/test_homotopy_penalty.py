"""The collision homotopy's surrogate as a penalty without slacks (Options.homotopy_form)."""
import dataclasses

import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import ProblemError


def test_auto_form_drops_the_slacks_where_an_object_is_carried_while_walking(g1):
    s1 = load_problem("s1_basket", model=g1)
    s1_data = ProblemData(s1, g1)
    assert solver.carries_object(s1_data)
    guide, final = solver.homotopy_stages(s1.options, s1_data)
    assert guide[3] == "penalty" and not guide[1]
    assert final[3] is False and final[1]  # the hard rows imply F >= 1: no surrogate in the final stage
    for case in ("case_lift_box", "case_one_step"):  # a lift in place; a step with nothing held
        prob = load_problem(case, model=g1)
        data = ProblemData(prob, g1)
        assert not solver.carries_object(data)
        with_homotopy = dataclasses.replace(prob.options, collision_homotopy=True)
        assert [s[3] for s in solver.homotopy_stages(with_homotopy, data)] == [True, True]


def test_forms_by_option(g1):
    prob = load_problem("case_lift_box", model=g1)
    data = ProblemData(prob, g1)
    slacks = dataclasses.replace(prob.options, homotopy_form="slacks")
    assert [s[3] for s in solver.homotopy_stages(slacks, data)] == [True, True]
    soft = dataclasses.replace(prob.options, homotopy_form="penalty", collision_hard_constraint=False)
    assert [s[3] for s in solver.homotopy_stages(soft, data)] == ["penalty", "penalty"]
    bad = dataclasses.replace(prob, options=dataclasses.replace(prob.options, homotopy_form="slack"))
    with pytest.raises(ProblemError, match="homotopy_form"):
        solver.solve(bad, g1)


def test_penalty_is_the_slack_form_minimised_over_the_slack(g1):
    """At the warm start of S1, with every slack at its least feasible value max(0, 1 - F), the
    slack form's cost equals the penalty form's (slacks pinned at 0, surrogate rows off)."""
    prob = load_problem("s1_basket", model=g1)
    data = ProblemData(prob, g1)
    win, wd = solver.get_window(g1, data.structure)
    K = data.grid.K
    _, ubw_s, lbg_s, _, Ps, W0 = data.fill(win, 2.0, False, True, True)
    _, ubw_p, lbg_p, _, Pp, _ = data.fill(win, 2.0, False, True, "penalty")
    sl = win.W["slack"]
    assert np.all(ubw_p[sl, :] == 0.0) and np.any(ubw_s[sl, :] > 0.0)
    rows = [win.G[f"c{i} homotopy surrogate"].start for i in range(len(data.pairs))]
    assert np.all(lbg_p[rows, :] == -np.inf) and np.any(lbg_s[rows, :] == 0.0)
    inside = 0
    for k in range(0, K - 1, 3):
        a, b = W0[:, k].copy(), W0[:, k + 1]
        a[sl] = 0.0
        g, f_pen = wd.F_gf(a, b, Pp[:, k])
        F = np.array(g).ravel()[rows] + 1.0  # F - 1 + s with s = 0
        on = ubw_s[sl, k] > 0
        a[sl] = np.where(on, np.maximum(0.0, 1.0 - F), 0.0)
        _, f_slack = wd.F_gf(a, b, Ps[:, k])
        np.testing.assert_allclose(float(f_pen), float(f_slack), rtol=1e-9, atol=1e-9)
        inside += int(np.count_nonzero(on & (F < 1.0)))
    assert inside > 0  # some pair is inside its surrogate, so the penalty was compared where it acts
