"""Options.carry_reach: a carried object's nominal comes in towards the body, raised, and goes back."""
import numpy as np
import pytest

from lomanip_to.discretize import CARRY_RAISE, ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import ProblemError


def _carry(g1, reach: float):
    prob = load_problem("s2_trolley", model=g1, options={"carry_reach": reach})
    data = ProblemData(prob, g1)
    return data, data.carry_rel["box"]


def test_the_carried_box_comes_within_the_reach_mid_carry_and_rises(g1):
    off, rel_off = _carry(g1, 0.0)
    on, rel_on = _carry(g1, 0.32)
    free = [k for k in range(on.grid.K) if on.obj_mode(k, "box") == "free"]
    t = on.grid.t
    mid = [k for k in free if t[free[0]] + 0.8 <= t[k] <= t[free[-1]] - 0.8]
    assert mid
    for k in mid:
        reach_off = np.hypot(*rel_off[k, :2])
        assert np.hypot(*rel_on[k, :2]) == pytest.approx(min(reach_off, 0.32), abs=1e-9)
        assert rel_on[k, 2] == pytest.approx(rel_off[k, 2] + CARRY_RAISE, abs=1e-9)
    # at the lift-off and at the set-down the box is where it was without the option
    for k in (free[0], free[-1]):
        if not np.isnan(rel_off[k, 0]):
            assert np.allclose(rel_on[k], rel_off[k], atol=1e-9)


def test_the_reach_is_validated(g1):
    from lomanip_to.problem import validate_problem

    prob = load_problem("case_lift_box", model=g1, options={"carry_reach": -0.1})
    with pytest.raises(ProblemError, match="carry_reach"):
        validate_problem(prob, g1)
