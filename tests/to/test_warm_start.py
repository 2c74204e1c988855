"""The stepping warm start: stance feet stay on their footholds, swing feet lift, hands follow."""
import numpy as np

from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import FEET, HANDS
from lomanip_to.warm_start import footholds, hand_targets


def _limbs(g1, X):
    return [g1.numeric(x)["limbs"] for x in X]


def test_stance_feet_do_not_slide_and_swing_feet_lift(g1):
    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    X = data.x_guess
    limbs = _limbs(g1, X)
    K = data.grid.K
    for f in FEET:
        for k in range(K - 1):
            c, cn = data.contact(k, f), data.contact(k + 1, f)
            if c is not None and cn is not None and c.object_id == cn.object_id:
                slide = np.linalg.norm(limbs[k + 1][f][0][:2] - limbs[k][f][0][:2])
                assert slide < 0.01, f"{f} slides {slide:.3f} m at t={data.grid.t[k]:.1f}"
            if c is not None:  # sole on its surface and level
                assert abs(limbs[k][f][0][2] - data._surface_height(c)) < 0.01
                assert abs(limbs[k][f][1][2, 2]) > 0.99
        swing = [k for k in range(K) if data.contact(k, f) is None]
        assert swing, f"{f} never swings in S1"
        assert max(limbs[k][f][0][2] for k in swing) > 0.04  # lifted, not dragged


def test_footholds_start_at_the_initial_feet_and_walk_towards_the_keyframes(g1):
    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    x0 = data.x_init
    feet = footholds(data, np.tile(x0, (data.grid.K, 1)))
    init = g1.numeric(x0)["limbs"]
    for f in FEET:
        assert np.allclose(feet[f][0, :3], init[f][0], atol=1e-6)
    # with the keyframe nominal, the feet at the first keyframe are the keyframe's feet
    k_kf, kf = min(data.kf_knots.items())
    kf_feet = g1.numeric(kf.x())["limbs"]
    for f in FEET:
        assert np.linalg.norm(g1.numeric(data.x_guess[k_kf])["limbs"][f][0][:2] - kf_feet[f][0][:2]) < 0.02


def test_hands_reach_their_contacts_in_the_warm_start(g1):
    data = ProblemData(load_problem("case_lift_box", model=g1), g1)
    limbs = _limbs(g1, data.x_guess)
    targets = hand_targets(data)
    n = 0
    for k in range(1, data.grid.K):
        for h in HANDS:
            if data.contact(k, h) is None:
                continue
            assert np.linalg.norm(limbs[k][h][0] - targets[h][0][k]) < 0.02
            n += 1
    assert n > 0
    # the box is lifted in this case: the targets follow its nominal pose up
    assert targets[HANDS[0]][0][-1][2] > targets[HANDS[0]][0][[k for k in range(data.grid.K)
                                                               if data.contact(k, HANDS[0])][0]][2] + 0.05


def test_no_keyframe_warm_start_keeps_the_initial_posture(g1):
    prob = load_problem("s1_basket", model=g1, options={"use_keyframe_warm_start": False})
    data = ProblemData(prob, g1)
    assert np.allclose(data.x_guess, data.x_init)


def _worst_body_penetration(g1, data, X):
    from lomanip_to.discretize import obj_prims_world
    from lomanip_to.warm_start import BODY_GROUPS

    worst = 0.0
    for o in data.prob.objects:
        if o.id in data.midx:
            continue
        for x in X:
            c = g1.numeric(x)["spheres"]
            for si, sph in enumerate(g1.spheres):
                if sph.group not in BODY_GROUPS:
                    continue
                for ctr, R, he in obj_prims_world(o):
                    q = np.abs(R.T @ (c[si] - ctr)) - he
                    worst = min(worst, np.linalg.norm(np.maximum(q, 0)) + min(q.max(), 0) - sph.radius)
    return -worst


def test_warm_start_keeps_the_body_further_out_of_fixed_furniture(g1):
    """S2 with the trolley 45 cm from the table (the old layout): placing the box between them,
    the nominal puts the pelvis ~8-11 cm into the table; the warm start's IK pushes the body out
    as far as the footholds allow."""
    data = ProblemData(load_problem("s2_trolley", {"trolley_position": [0.90, -1.10], "side_gap": 0.50}, model=g1), g1)
    nominal = _worst_body_penetration(g1, data, data._keyframe_nominal())
    guess = _worst_body_penetration(g1, data, data.x_guess)
    assert nominal > 0.05
    assert guess < 0.75 * nominal, (guess, nominal)


def test_s2_warm_start_is_clear_of_furniture(g1):
    """The S2 layout leaves room to stand and squat; with the routes round the table and the
    trolley, the warm start's body stays out of both (the hands may touch)."""
    data = ProblemData(load_problem("s2_trolley", model=g1), g1)
    assert _worst_body_penetration(g1, data, data.x_guess) < 0.01


def test_carried_box_moves_with_the_base_and_the_warm_start_has_no_jumps(g1):
    """S1's carry: the box's nominal follows the base, so the IK does not twist the robot to reach
    it (before: the box moved on its own clock, 0.5 m off the base; yaw jumped 0.9 rad per knot)."""
    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    X, box = data.x_guess, data.obj_nom["box"]
    carried = [k for k in range(data.grid.K) if data.obj_mode(k, "box") == "free"]
    assert len(carried) > 20
    reach = max(np.linalg.norm(box[k, :2] - X[k, :2]) for k in carried)
    assert reach < 0.6, f"box {reach:.2f} m from the base"
    ks = np.array(carried[:-1])
    assert np.abs(X[ks + 1, 5] - X[ks, 5]).max() < 0.35
    speed = np.abs(X[ks + 1, :3] - X[ks, :3]).max(axis=1) / (data.grid.t[ks + 1] - data.grid.t[ks])
    # 1.21 m/s since session 37: the set-down's squat to the lower grip (grip_z 0.05) drops the
    # base 12 cm over one 0.1 s knot at 8.8 s; the carry's steps stay under 0.85 m/s
    assert speed.max() < 1.3, f"base speed {speed.max():.2f} m/s"


def test_hands_approach_their_contacts_from_outside(g1):
    from lomanip_to.warm_start import APPROACH_OFFSET, APPROACH_TIME, APPROACH_WEIGHT

    data = ProblemData(load_problem("case_lift_box", model=g1), g1)
    targets = hand_targets(data)
    t = data.grid.t
    for h in HANDS:
        first = next(k for k in range(data.grid.K) if data.contact(k, h) is not None)
        c = data.contact(first, h)
        outside = np.asarray(c.position) + APPROACH_OFFSET * np.asarray(c.normal) / np.linalg.norm(c.normal)
        before = [k for k in range(1, first) if t[first] - t[k] <= APPROACH_TIME + 1e-9]
        assert before, "the fixture has knots just before the grasp"
        for k in before:
            np.testing.assert_allclose(targets[h][0][k], outside, atol=1e-9)
            assert targets[h][1][k] == APPROACH_WEIGHT
        earlier = [k for k in range(1, first) if k not in before]
        assert all(targets[h][1][k] == 0 for k in earlier)  # no target further back
