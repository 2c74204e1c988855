"""Options.carried_object_clearance: the collision rows keep a carried object off the body."""
import numpy as np
import pytest

from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def test_the_clearance_applies_only_while_carried_and_not_to_the_holding_arms(g1):
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(carried_object_clearance=0.05)
    data = ProblemData(prob, g1)
    groups = [s.group for s in g1.spheres]
    torso = groups.index("torso")
    forearm = groups.index("left_forearm")
    shin = groups.index("left_shin")
    modes = [data.obj_mode(k, "box") for k in range(data.grid.K)]
    carried = modes.index("free")
    resting = modes.index("supported") if "supported" in modes else 0
    assert data._clearance(torso, carried, "box") == pytest.approx(0.05)
    assert data._clearance(forearm, carried, "box") == 0.0
    assert data._clearance(shin, carried, "box") == pytest.approx(0.05)
    assert data._clearance(torso, resting, "box") == 0.0
    off = ProblemData(load_problem("case_lift_box", model=g1), g1)
    assert off._clearance(torso, carried, "box") == 0.0
    assert np.isclose(off._clearance(shin, carried, "box"), 0.03)
