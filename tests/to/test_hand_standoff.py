"""Options.hand_standoff: a touching hand holds its hand point this far outside the surface (a ball
of that radius), its force acting at the surface point below it; 0 keeps the point on the surface."""
import numpy as np
import pytest

from lomanip_to import checks, solver
from lomanip_to.discretize import ProblemData, obj_prims_world
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import ProblemError, validate_problem

STANDOFF = 0.04


def test_the_standoff_is_part_of_the_structure_and_checked(g1):
    prob = load_problem("case_lift_box", model=g1)
    off = ProblemData(prob, g1).structure
    prob.options = prob.options.replaced(hand_standoff=STANDOFF)
    on = ProblemData(prob, g1).structure
    assert off.hand_standoff == 0.0 and on.hand_standoff == STANDOFF and off.key() != on.key()
    for bad in (-0.01, 0.2, float("nan")):
        prob.options = prob.options.replaced(hand_standoff=bad)
        with pytest.raises(ProblemError, match="hand_standoff"):
            validate_problem(prob, g1)


def test_the_warm_start_aims_the_hands_off_the_surface(g1):
    from lomanip_to.warm_start import hand_targets

    prob = load_problem("case_lift_box", model=g1)
    base = hand_targets(ProblemData(prob, g1))
    prob.options = prob.options.replaced(hand_standoff=STANDOFF)
    data = ProblemData(prob, g1)
    moved = hand_targets(data)
    k = next(k for k in range(data.grid.K) if data.contact(k, "left_hand") is not None)
    n = np.asarray(data.contact(k, "left_hand").normal, float)
    np.testing.assert_allclose(moved["left_hand"][0][k] - base["left_hand"][0][k], STANDOFF * n / np.linalg.norm(n),
                               atol=1e-9)


def test_a_lift_with_a_standoff_holds_the_hands_off_the_faces_and_the_forces_on_them(g1):
    """case_lift_box with a 4 cm standoff converges and passes the checks; at every held knot the
    hand point is 4 cm out along the face's normal from the result's contact point, which lies on
    the box's face; the wrists no longer reach into the box as they do at 0 (3 cm)."""
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(hand_standoff=STANDOFF)
    res = solver.solve(prob, g1)
    assert res.stats.converged and res.success, res.stats.status_message()
    box = next(o for o in prob.objects if o.id == "box")
    held = 0
    for k in range(len(res.t_knots)):
        for h in ("left_hand", "right_hand"):
            if res.contact_objects_knots[h][k] != "box":
                continue
            held += 1
            pt = g1.numeric(res.x_knots[k])["limbs"][h][0]
            c = res.points_knots[h][k]
            np.testing.assert_allclose(pt - c, STANDOFF * res.normals_knots[h][k], atol=2e-3)
            pose = res.object_pose_knots["box"][k]
            # the force's point is on the box's surface
            d = min(checks.sphere_box_distance(c, cc, R, he, 0.0) for cc, R, he in obj_prims_world(box, pose[:3], pose[3:]))
            assert abs(d) < 3e-3, (k, h, d)
    assert held > 10
    assert res.stats.checks["penetration"]["held_object_forearm"] < 0.015
