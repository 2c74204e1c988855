"""Options.body_object_clearance: the collision rows keep the trunk and thighs off every object."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import LEG_OBJECT_CLEARANCE, ProblemData
from lomanip_to.fixtures import load_problem


def test_the_clearance_applies_to_trunk_and_thighs_only(g1):
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(body_object_clearance=0.03)
    data = ProblemData(prob, g1)
    groups = [s.group for s in g1.spheres]
    for group in ("pelvis", "torso", "head", "left_thigh", "right_thigh"):
        for k in (0, data.grid.K - 1):
            assert data._clearance(groups.index(group), k, "table") == pytest.approx(0.03), group
    for group in ("left_hand", "right_forearm", "left_upper_arm"):
        assert data._clearance(groups.index(group), 0, "table") == 0.0, group
    assert data._clearance(groups.index("left_shin"), 0, "table") == pytest.approx(LEG_OBJECT_CLEARANCE)
    off = ProblemData(load_problem("case_lift_box", model=g1), g1)
    assert off._clearance(groups.index("torso"), 0, "table") == 0.0


@pytest.mark.parametrize("clearance", [0.0, 0.04])
def test_the_hard_rows_keep_the_pelvis_that_far_from_the_table(g1, clearance):
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(body_object_clearance=clearance)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, _, _, _ = data.fill(win, 6.0, True, False, False)  # the final (hard) stage's bounds
    pelvis = [s.name for s in g1.spheres].index("pelvis")
    i = next(i for i, (s, (oid, _)) in enumerate(data.pairs) if s == pelvis and oid == "table")
    row = lbg[win.G[f"c{i} collision"], 0]
    assert np.all(row == pytest.approx(clearance))
