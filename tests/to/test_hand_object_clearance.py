"""Options.hand_object_clearance: the hands keep off still objects they never touch."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def _data(g1, clearance):
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(hand_object_clearance=clearance)
    return ProblemData(prob, g1)


def test_the_clearance_applies_to_the_hands_against_the_table_only(g1):
    data = _data(g1, 0.04)
    groups = [s.group for s in g1.spheres]
    for k in (0, data.grid.K - 1):
        for side in ("left", "right"):
            assert data._clearance(groups.index(f"{side}_hand"), k, "table") == pytest.approx(0.04)
            # the box moves and the hands hold it: no clearance against it
            assert data._clearance(groups.index(f"{side}_hand"), k, "box") == 0.0
    for group in ("left_forearm", "torso", "left_upper_arm"):
        assert data._clearance(groups.index(group), 0, "table") == 0.0, group
    assert _data(g1, 0.0)._clearance(groups.index("left_hand"), 0, "table") == 0.0


def test_the_hard_rows_keep_the_hands_that_far_from_the_table(g1):
    data = _data(g1, 0.04)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, _, _, _ = data.fill(win, 6.0, True, False, False)  # the final (hard) stage's bounds
    hands = {i for i, s in enumerate(g1.spheres) if s.group.endswith("_hand")}
    rows = [i for i, (s, (oid, _)) in enumerate(data.pairs) if s in hands and oid == "table"]
    assert rows, "the lift has hand-table pairs"
    for i in rows:
        assert np.all(lbg[win.G[f"c{i} collision"], 0] == pytest.approx(0.04))
