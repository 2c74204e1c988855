"""lomanip_to.checks: feet that must not slide, penetrations, placement goals and grips."""

from types import SimpleNamespace

import numpy as np
import pytest

from lomanip_to.checks import foot_slip


def _result(left_points, left_objects):
    n = len(left_points)
    return SimpleNamespace(
        t_knots=np.arange(n) * 0.1,
        points_knots={"left_foot": np.asarray(left_points, float), "right_foot": np.zeros((n, 3))},
        contact_objects_knots={"left_foot": left_objects, "right_foot": ["floor"] * n},
    )


def test_planted_stance_and_free_swing_pass():
    res = _result([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0.1, 0, 0.05], [0.2, 0, 0]], ["floor", "floor", "", "", "floor"])
    assert foot_slip(res)[0] == pytest.approx(0.0)


def test_lift_off_knot_that_already_moved_is_caught():
    # knot 1 is the last contact knot; its force acts until knot 2, where the sole is 15 cm ahead
    res = _result([[0, 0, 0], [0, 0, 0], [0.15, 0, 0.04], [0.2, 0, 0.05], [0.3, 0, 0]], ["floor", "floor", "", "", "floor"])
    value, (foot, t) = foot_slip(res)
    assert value == pytest.approx(np.hypot(0.15, 0.04))
    assert foot == "left_foot" and t == pytest.approx(0.1)


def test_a_carried_box_below_the_floor_counts_as_penetration(g1):
    """The physical check sees a moving object's bottom corners under the floor (S1's old plans
    passed with the box 14 cm into the floor)."""
    from types import SimpleNamespace

    from lomanip_to.checks import penetration_per_knot
    from lomanip_to.discretize import ProblemData
    from lomanip_to.fixtures import load_problem

    prob = load_problem("case_lift_box", model=g1)
    data = ProblemData(prob, g1)
    K = 3
    x = np.array(prob.initial_configuration, float)
    bottom = prob.object("box").bottom_z()
    # far from the robot and the table, resting on the floor
    box = np.tile(np.r_[3.0, 0.0, -bottom, 0.0, 0.0, 0.0], (K, 1))
    res = SimpleNamespace(t_knots=np.arange(K) * 0.1, x_knots=np.tile(x, (K, 1)), object_pose_knots={"box": box})
    total, worst, _ = penetration_per_knot(g1, data, res)
    assert worst < 1e-9
    box[1, 2] -= 0.03   # 3 cm down at the middle knot
    box[2, 3] = 0.1     # rolled, so one bottom edge dips (by 1.4 cm)
    total, worst, k = penetration_per_knot(g1, data, res)
    assert worst == pytest.approx(0.03, abs=1e-9) and k == 1
    assert total[0] < 1e-9 and total[1] > 0.03 and total[2] > 0.0


def test_an_object_short_of_its_placement_goal_fails_the_check(g1):
    """Goals are costs: a converged plan can leave the object where it was (every S2 and demo push
    did, 0.25-0.5 m short). The check reads the object's pose at the goal's time."""
    from lomanip_to.checks import TOL, placement_error
    from lomanip_to.discretize import ProblemData
    from lomanip_to.fixtures import load_problem

    prob = load_problem("case_lift_box", model=g1)
    assert prob.placement_goals
    data = ProblemData(prob, g1)
    g = prob.placement_goals[0]
    K = len(data.grid.t)
    at_goal = np.tile(np.r_[g.position, 0.0, 0.0, g.yaw], (K, 1))
    res = SimpleNamespace(t_knots=data.grid.t, object_pose_knots={g.object_id: at_goal})
    dp, dyaw, oid, _ = placement_error(data, res)
    assert dp < 1e-9 and dyaw < 1e-9 and oid == g.object_id
    o = prob.object(g.object_id)
    stayed = np.tile(np.r_[o.position, o.rpy()], (K, 1))
    res.object_pose_knots = {g.object_id: stayed}
    dp, _, oid, _ = placement_error(data, res)
    assert dp == pytest.approx(np.linalg.norm(np.subtract(o.position, g.position))) and dp > TOL["placement"]


def test_the_to_wheels_resist_rolling_as_the_sims_do():
    """The TO's rolling objects may take the sim trolley's wheel resistance, no more (else the plan
    stops the trolley in a way MuJoCo cannot, or, at 0, cannot stop it at all)."""
    from lomanip_sim.scenario import S2TrolleyParams
    from lomanip_to.discretize import WHEEL_ROLLING_RESISTANCE

    assert WHEEL_ROLLING_RESISTANCE == S2TrolleyParams().wheel_rolling_resistance > 0


def test_rolling_rows_are_on_only_while_rolling(g1):
    """The nonholonomic row holds a rolling object only (a carried box on it could not move sideways),
    and the wheels' longitudinal force is bounded by their rolling resistance."""
    from lomanip_to import solver
    from lomanip_to.discretize import WHEEL_ROLLING_RESISTANCE, ProblemData
    from lomanip_to.fixtures import load_problem

    data = ProblemData(load_problem("s2_trolley", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, ubg, _, _ = data.fill(win, 6.0, True, True, True)
    for oid, j in data.midx.items():
        slip, wheel = win.G[f"o{j} nonholonomic: no lateral slip"], win.G[f"o{j} rolling: no longitudinal wheel force"]
        for k in range(data.grid.K):
            rolling = data.obj_mode(k, oid) == "rolling"
            assert np.all(np.isfinite(lbg[slip, k])) == rolling, (oid, k)
            f = WHEEL_ROLLING_RESISTANCE / (g1.mass * 9.81)
            assert np.allclose(ubg[wheel, k], f if rolling else np.inf), (oid, k)
    assert any(data.obj_mode(k, "trolley") == "rolling" for k in range(data.grid.K))
    assert any(data.obj_mode(k, "box") == "free" for k in range(data.grid.K))


def test_a_hand_turning_on_the_box_it_holds_is_caught(g1):
    """A pressed palm sticks: turning the wrist while the hand holds the box fails the check (S1's
    plans turned a hand up to 2.9 rad on the box before the grip rows)."""
    from lomanip_to.checks import TOL, hand_grip_rotation

    K = 4
    x = np.tile(g1.x_stand(), (K, 1))
    box = np.tile([0.4, 0.0, 0.5, 0.0, 0.0, 0.0], (K, 1))
    objs = {"left_hand": ["", "box", "box", "box"], "right_hand": [""] * K}
    res = SimpleNamespace(t_knots=np.arange(K) * 0.1, x_knots=x, object_pose_knots={"box": box},
                          contact_objects_knots=objs)
    assert hand_grip_rotation(g1, res)[0] < 1e-9
    # the box and the body turn together: the grip is unchanged
    box[:, 5] = x[:, 5] = [0.0, 0.2, 0.4, 0.6]
    assert hand_grip_rotation(g1, res)[0] < 1e-9
    # the wrist yaw turns 0.3 rad at the last knot
    x[3, 6 + g1.joint_names.index("left_wrist_yaw_joint")] += 0.3
    value, (hand, t) = hand_grip_rotation(g1, res)
    assert value == pytest.approx(0.3, abs=1e-6) and value > TOL["hand_grip_rotation"]
    assert hand == "left_hand" and t == pytest.approx(0.3)
