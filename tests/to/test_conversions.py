"""TO problem <-> ROS messages: the fixtures survive a round trip; bad messages give error codes."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_to import conversions as conv
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import INVALID_REQUEST, ProblemError, validate_problem


@pytest.fixture(scope="module")
def model():
    from lomanip_to.solver import default_model

    return default_model()


@pytest.mark.parametrize("name", ["case_lift_box", "case_one_step", "s1_basket"])
def test_fixture_round_trip(model, name):
    prob = load_problem(name, model=model)
    req = conv.request_from_problem(prob, model.joint_names)
    back = conv.problem_from_request(req, model.joint_names)
    validate_problem(back, model)
    np.testing.assert_allclose(back.initial_configuration, prob.initial_configuration, atol=1e-9)
    assert [o.id for o in back.objects] == [o.id for o in prob.objects]
    for a, b in zip(back.objects, prob.objects):
        np.testing.assert_allclose(a.position, b.position, atol=1e-9)
        assert a.mass == pytest.approx(b.mass)
        np.testing.assert_allclose(a.inertia_matrix(), b.inertia_matrix(), atol=1e-9)
        assert [(p.kind, tuple(p.size)) for p in a.primitives] == [(p.kind, tuple(p.size)) for p in b.primitives]
    assert len(back.phases) == len(prob.phases)
    for a, b in zip(back.phases, prob.phases):
        assert (a.start, a.end, a.phase_type, a.subtask_index) == pytest.approx((b.start, b.end, b.phase_type, b.subtask_index))
        assert set(a.contacts) == set(b.contacts)
        for limb in a.contacts:
            ca, cb = a.contacts[limb], b.contacts[limb]
            assert ca.object_id == cb.object_id
            if cb.position is None:
                assert ca.position is None
            else:
                np.testing.assert_allclose(ca.position, cb.position, atol=1e-9)
                np.testing.assert_allclose(ca.normal, np.asarray(cb.normal) / np.linalg.norm(cb.normal), atol=1e-9)
        assert {k: (m.mode, m.support, m.attached_to) for k, m in a.objects.items()} == \
               {k: (m.mode, m.support, m.attached_to) for k, m in b.objects.items()}
    for a, b in zip(back.keyframes, prob.keyframes):
        np.testing.assert_allclose(a.x(), b.x(), atol=1e-9)
    # placement goals keep their time (S1's box at the place keyframe; the lift's at the end)
    assert [(g.object_id, g.time) for g in back.placement_goals] == [(g.object_id, g.time) for g in prob.placement_goals]
    for a, b in zip(back.placement_goals, prob.placement_goals):
        np.testing.assert_allclose(a.position, b.position, atol=1e-9)
        assert a.yaw == pytest.approx(b.yaw)


def test_foreign_joint_names_are_refused(model):
    prob = load_problem("case_lift_box", model=model)
    req = conv.request_from_problem(prob, model.joint_names)
    req.keyframes.keyframes[0].joints.name[0] = "panda_joint1"
    with pytest.raises(ProblemError) as err:
        conv.problem_from_request(req, model.joint_names)
    assert err.value.code == INVALID_REQUEST and "panda_joint1" in err.value.message


def test_unknown_motion_mode_is_refused(model):
    prob = load_problem("case_lift_box", model=model)
    req = conv.request_from_problem(prob, model.joint_names)
    phase = next(p for p in req.contact_schedule.phases if p.object_motions)
    phase.object_motions[0].mode = "teleport"
    with pytest.raises(ProblemError, match="teleport"):
        conv.problem_from_request(req, model.joint_names)


def test_durations_round_trip_without_losing_a_second():
    from lomanip_to.conversions import duration_to_s, s_to_duration

    for t in (0.0, 0.1, 6.9999999999, 7.9999999996, 12.5, 35.2):
        d = s_to_duration(t)
        assert 0 <= d.nanosec < 1_000_000_000
        assert abs(duration_to_s(d) - t) < 1e-9


def test_options_round_trip_the_inertial_torque_groups(model):
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    assert conv.options_from_msg(TrajectoryOptions()).inertial_torque_groups == Options().inertial_torque_groups
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(inertial_torque_groups=())
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).inertial_torque_groups == ()
    msg = TrajectoryOptions(inertial_torque_groups=["waist", "left_hand"])
    assert conv.options_from_msg(msg).inertial_torque_groups == ("waist", "left_hand")


def test_options_round_trip_the_solver_options(model):
    """Text values become ipopt's types (int, float, string); the node's own ipopt options stay
    unless the request names the same option."""
    from lomanip_msgs.msg import SolverOption, TrajectoryOptions
    from lomanip_to.problem import Options

    msg = TrajectoryOptions(solver_options=[SolverOption(name="perturb_always_cd", value="yes"),
                                            SolverOption(name="acceptable_iter", value="5"),
                                            SolverOption(name="tol", value="1e-5")])
    base = Options(ipopt={"mu_strategy": "monotone", "tol": 1e-3})
    got = conv.options_from_msg(msg, base).ipopt
    assert got == {"mu_strategy": "monotone", "perturb_always_cd": "yes", "acceptable_iter": 5, "tol": 1e-5}
    assert isinstance(got["acceptable_iter"], int)
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(ipopt={"perturb_always_cd": "yes", "acceptable_iter": 5})
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).ipopt == {"perturb_always_cd": "yes", "acceptable_iter": 5}


def test_options_round_trip_the_cost_weights(model):
    """Request weights go over the node's own; a problem's weights travel in its request."""
    from lomanip_msgs.msg import CostWeight, TrajectoryOptions
    from lomanip_to.problem import Options

    msg = TrajectoryOptions(weights=[CostWeight(name="w_carry_pose", value=500.0)])
    base = Options(weights={"w_goal": 2e3, "w_carry_pose": 1.0})
    assert conv.options_from_msg(msg, base).weights == {"w_goal": 2e3, "w_carry_pose": 500.0}
    assert conv.options_from_msg(TrajectoryOptions()).weights == {}
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(weights={"w_carry_pose": 500.0})
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).weights == {"w_carry_pose": 500.0}


def test_options_round_trip_the_subtask_options(model):
    """A problem's subtask options travel in its request (YAML per subtask) and read back equal;
    without any the node's own stay."""
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    prob = load_problem("s1_basket", model=model)
    assert prob.options.subtask_options[2]["weights"]["hip_margin"] == 0.08  # the fixture asks for them
    prob.options = prob.options.replaced(subtask_options={**prob.options.subtask_options,
                                                          0: {"inertial_torque_groups": ("waist",),
                                                              "ipopt": {"tol": 1e-5}}})
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).subtask_options == prob.options.subtask_options
    base = Options(subtask_options={1: {"dt_lift": 0.1}})
    assert conv.options_from_msg(TrajectoryOptions(), base).subtask_options == {1: {"dt_lift": 0.1}}


@pytest.mark.parametrize("text, match", [("[1, 2]", "must be a mapping"), ("{a: [", "not YAML"),
                                         ("{arm_body_self_pairs: true}", "given twice")])
def test_bad_subtask_options_are_invalid_requests(text, match):
    from lomanip_msgs.msg import SubtaskOptions, TrajectoryOptions

    entries = [SubtaskOptions(subtask_index=1, options_yaml=text)]
    if match == "given twice":
        entries.append(SubtaskOptions(subtask_index=1, options_yaml="{}"))
    with pytest.raises(ProblemError, match=match) as err:
        conv.options_from_msg(TrajectoryOptions(subtask_options=entries))
    assert err.value.code == INVALID_REQUEST


def test_subtask_options_naming_unknown_options_or_subtasks_are_refused_before_the_solve(model):
    from lomanip_msgs.msg import SubtaskOptions

    prob = load_problem("case_one_step", model=model)
    for entry, match in [(SubtaskOptions(subtask_index=0, options_yaml="{warp_speed: 9}"), "unknown option"),
                         (SubtaskOptions(subtask_index=7, options_yaml="{dt_lift: 0.1}"), "no subtask 7")]:
        req = conv.request_from_problem(prob, model.joint_names)
        req.options.subtask_options = [entry]
        with pytest.raises(ProblemError, match=match) as err:
            validate_problem(conv.problem_from_request(req, model.joint_names), model)
        assert err.value.code == INVALID_REQUEST


def test_options_round_trip_the_waist_yaw_range(model):
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    assert conv.options_from_msg(TrajectoryOptions()).waist_yaw_range == Options().waist_yaw_range == 0.0
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(waist_yaw_range=0.8)
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).waist_yaw_range == 0.8
    assert conv.options_from_msg(TrajectoryOptions(waist_yaw_range=-1.0)).waist_yaw_range == 0.0


def test_options_round_trip_the_single_support_com_lateral(model):
    """The message's default is the TO's; a task's tighter margin survives the trip; <= 0 is off."""
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    assert conv.options_from_msg(TrajectoryOptions()).single_support_com_lateral == Options().single_support_com_lateral
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(single_support_com_lateral=0.04)
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).single_support_com_lateral == 0.04
    prob.options = prob.options.replaced(single_support_com_lateral=None)
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).single_support_com_lateral is None



@pytest.mark.parametrize("name, value", [("interval_momentum_tolerance", 0.5), ("upper_body_acceleration_limit", 30.0),
                                         ("upper_body_speed_limit", 3.0), ("carried_object_clearance", 0.05), ("dt_lift", 0.1), ("dt_reach", 0.1),
                                         ("body_object_clearance", 0.03), ("hand_object_clearance", 0.04),
                                         ("carry_reach", 0.32), ("placement_tolerance", 0.04)])
def test_options_round_trip_the_rows_on_the_motion_between_knots(model, name, value):
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    assert getattr(conv.options_from_msg(TrajectoryOptions()), name) == getattr(Options(), name) == 0.0
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(**{name: value})
    req = conv.request_from_problem(prob, model.joint_names)
    assert getattr(conv.options_from_msg(req.options), name) == value
    assert getattr(conv.options_from_msg(TrajectoryOptions(**{name: -1.0})), name) == 0.0  # off


@pytest.mark.parametrize("name", ["lift_with_previous_segment", "segment_moving_objects", "load_in_double_support_margin",
                                  "resting_object_dynamics", "forearm_clear_of_held_object"])
def test_options_round_trip_the_switches(model, name):
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    assert getattr(conv.options_from_msg(TrajectoryOptions()), name) is getattr(Options(), name) is False
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(**{name: True})
    req = conv.request_from_problem(prob, model.joint_names)
    assert getattr(req.options, name) is True
    assert getattr(conv.options_from_msg(req.options), name) is True


def test_options_round_trip_the_front_cop_margin(model):
    """``cop_margin_front`` travels in TrajectoryOptions with the TO's default (0.02 m); a bad value
    reaches the TO's validation, which refuses it before any solve."""
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import INVALID_REQUEST, Options, ProblemError, validate_problem

    assert conv.options_from_msg(TrajectoryOptions()).cop_margin_front == Options().cop_margin_front == 0.02
    assert conv.options_from_msg(TrajectoryOptions()).cop_margin_side == Options().cop_margin_side == 0.01
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(cop_margin_front=0.04)
    req = conv.request_from_problem(prob, model.joint_names)
    assert conv.options_from_msg(req.options).cop_margin_front == 0.04
    prob.options = prob.options.replaced(cop_margin_side=0.015)
    assert conv.options_from_msg(conv.request_from_problem(prob, model.joint_names).options).cop_margin_side == 0.015
    prob.options = conv.options_from_msg(TrajectoryOptions(cop_margin_front=-0.01))
    with pytest.raises(ProblemError) as e:
        validate_problem(prob, model)
    assert e.value.code == INVALID_REQUEST


@pytest.mark.parametrize("name, value", [("hand_standoff", 0.04), ("final_warm_start_max_violation", 1.0), ("final_cold_retry", True), ("hold_placement_goals", True),
                                         ("collision_screen_distance", 0.1),
                                         ("cop_margin_front", 0.04)])
def test_options_round_trip_the_hand_and_warm_start_values(model, name, value):
    """The message's defaults are the TO's; S1's task file values survive the trip."""
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_to.problem import Options

    assert getattr(conv.options_from_msg(TrajectoryOptions()), name) == getattr(Options(), name)
    prob = load_problem("case_one_step", model=model)
    prob.options = prob.options.replaced(**{name: value})
    req = conv.request_from_problem(prob, model.joint_names)
    assert getattr(conv.options_from_msg(req.options), name) == value


def test_foot_headings_round_trip_and_nan_is_none(model):
    from dataclasses import replace

    prob = load_problem("case_one_step", model=model)
    ph0 = prob.phases[0]
    prob.phases[0] = replace(ph0, contacts={**ph0.contacts,
                                            "left_foot": replace(ph0.contacts["left_foot"], heading=0.3)})
    req = conv.request_from_problem(prob, model.joint_names)
    back = conv.problem_from_request(req, model.joint_names)
    assert back.phases[0].contacts["left_foot"].heading == pytest.approx(0.3)
    assert back.phases[0].contacts["right_foot"].heading is None        # NaN on the wire
    assert all(c.heading is None for ph in back.phases[1:] for c in ph.contacts.values())   # empty list
    req.contact_schedule.phases[0].contact_headings = [0.3]
    with pytest.raises(ProblemError, match="contact_headings"):
        conv.problem_from_request(req, model.joint_names)


def test_a_hand_heading_or_an_infinite_one_is_refused(model):
    from dataclasses import replace

    prob = load_problem("case_one_step", model=model)
    ph0 = prob.phases[0]
    prob.phases[0] = replace(ph0, contacts={**ph0.contacts,
                                            "left_foot": replace(ph0.contacts["left_foot"], heading=float("inf"))})
    with pytest.raises(ProblemError, match="non-finite"):
        validate_problem(prob, model)
