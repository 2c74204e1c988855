"""The homotopy guide keeps the clearance the final stage's hard collision rows ask for."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import LEG_OBJECT_CLEARANCE, ProblemData
from lomanip_to.fixtures import load_problem


def test_guide_surrogate_grows_by_the_leg_clearance(g1):
    """S1's grasp keyframe has the shins inside the box: a guide whose surrogate allowed contact
    ended 4.6 cm short of the final stage's 3 cm leg clearance and that stage failed from there
    ("locally infeasible"). In the guide (no hard rows) the primitives grow by the clearance of
    the sphere they are paired with; in the final stage they have their true size."""
    prob = load_problem("s1_basket", model=g1)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    guide, final = solver.homotopy_stages(prob.options)
    assert not guide[1] and final[1]  # hard rows off in the guide, on in the final stage
    Pg = data.fill(win, *guide)[4]
    Pf = data.fill(win, *final)[4]
    legs = others = 0
    for i, (s, (oid, pi)) in enumerate(data.pairs):
        true = prob.object(oid).primitives[pi].half_extents()
        # per knot: the fixture's carried_object_clearance grows the carried box's pairs while it is carried
        grow = np.array([data._clearance(s, k, oid) for k in range(data.grid.K)])
        np.testing.assert_allclose(Pf[win.P[f"c{i}_half"], :], np.tile(true[:, None], (1, data.grid.K)))
        np.testing.assert_allclose(Pg[win.P[f"c{i}_half"], :], true[:, None] + grow[None, :])
        legs += data._clearance(s) == LEG_OBJECT_CLEARANCE
        others += data._clearance(s) == 0.0
    assert legs and others
