"""The ROS-free plan pipeline: sim scene -> synthetic perception -> retargeted keyframes -> TO problem."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_planner import offline
from lomanip_to.problem import PlacementGoal, validate_problem


@pytest.fixture(scope="module")
def s2_plan():
    goal = PlacementGoal("box", (0.20, -1.10, 0.475), 0.0)
    prompts = ["pick up the box from the table", "place the box on the trolley", "push the trolley forward"]
    return offline.plan("s2_trolley", prompts, {"box": goal}, solve=False)


def test_s2_prompts_give_feasible_keyframes(s2_plan):
    assert [kf.index for kf in s2_plan.keyframes] == [0, 1, 2]
    for kf in s2_plan.keyframes:
        r = kf.retarget
        assert max(r.residuals.values()) <= 0.01, r.residuals
        assert r.within_joint_limits and r.min_self_distance >= 0.0
        assert max(r.foot_tilt.values()) < 0.02          # feet flat in stance
    # placing: both hands around the goal, above the trolley deck
    hands = np.array([c.position for c in s2_plan.keyframes[1].contacts if c.limb.endswith("hand")])
    assert np.linalg.norm(hands.mean(axis=0)[:2] - [0.20, -1.10]) < 0.1
    # pushing: both hands on the trolley
    assert {c.object_id for c in s2_plan.keyframes[2].contacts if c.limb.endswith("hand")} == {"trolley"}


def test_s2_problem_is_valid_and_ordered(s2_plan):
    validate_problem(s2_plan.problem)
    times = [s2_plan.problem.keyframe_time(k) for k in s2_plan.problem.keyframes]
    assert times == sorted(times) and times[-1] <= s2_plan.problem.duration
    assert s2_plan.problem.placement_goals[0].object_id == "box"
    assert set(s2_plan.timings) == {"perception", "retargeting"}


def test_s2_footsteps_go_round_the_trolley(s2_plan):
    """Walking from the trolley's side (box placed) to its handle, no foothold lands on it."""
    from lomanip_to.route import footprint_of

    trolley = next(o for o in s2_plan.problem.objects if o.id == "trolley")
    fp = footprint_of(trolley, trolley.position, trolley.rpy())
    kf_push = s2_plan.problem.keyframe_time(s2_plan.problem.keyframes[2])
    feet = [c.position for ph in s2_plan.problem.phases if ph.subtask_index == 2 and ph.end <= kf_push
            for limb, c in ph.contacts.items() if limb.endswith("foot")]
    assert feet
    assert min(fp.distance(p) for p in feet) > 0.1


@pytest.fixture(scope="module")
def s1_plan():
    goal = PlacementGoal("box", (1.42, 1.0, 0.15), 0.0)
    prompts = ["pick up the box", "place the box next to the shelf", "step on the box and grab the basket"]
    return offline.plan("s1_basket", prompts, {"box": goal}, {"box_yaw": 0.0}, solve=False)


def test_s1_from_prompts_has_the_fixtures_structure(s1_plan):
    """Like the hand-written S1 fixture (18.2 s: 2 steps to the box, 8 carrying it, 2 onto it): the
    robot works the box from its own side, carries it at most 0.35 m a step, squats moderately. The
    carry turns 55 degrees to leave and 60 back in small steps (lomanip_planner.footsteps): 12 steps,
    none landing further than 0.43 m from the stance foot (before session 53: 8, the first 0.48 m
    away, 0.47 m aside)."""
    from lomanip_to.problem import WALKING

    prob = s1_plan.problem
    assert prob.duration < 24.0 and len(prob.phases) < 52   # 23.5 s: the grab's overhead reach is 2.1 s (session 55)
    walking = [ph for ph in prob.phases if ph.phase_type == WALKING]
    assert sum(ph.subtask_index == 0 for ph in walking) <= 4           # no walk round the box
    assert sum("box" in ph.objects for ph in walking) <= 12            # carry: fixture 8
    stances = [ph for ph in prob.phases if ph.subtask_index == 1 and ph.phase_type != WALKING]
    widths = [np.linalg.norm(np.subtract(ph.contacts["left_foot"].position, ph.contacts["right_foot"].position)[:2])
              for ph in stances]
    assert max(widths) < 0.43
    pick, place = s1_plan.keyframes[0], s1_plan.keyframes[1]
    assert pick.qpos[0] < 0.7 - 0.3 and abs(pick.qpos[1]) < 0.15     # in front of the box (x = 0.7)
    assert pick.qpos[2] > 0.3 and place.qpos[2] > 0.3                  # not the 0.16-0.21 m squats
    # the grasp is rigid: the place keyframe's hands sit where the pick's did, moved with the box
    hp = {c.limb: np.asarray(c.position) - [0.7, 0.0, 0.15] for c in pick.contacts if c.limb.endswith("hand")}
    g = prob.placement_goals[0]
    c, s = np.cos(g.yaw), np.sin(g.yaw)
    for t in place.contacts:
        if t.limb.endswith("hand"):
            d = np.asarray(t.position) - np.asarray(g.position)
            assert np.allclose([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]], hp[t.limb], atol=1e-6)
    # the robot places the box standing in front of the shelf (x = 1.70), facing it
    assert place.qpos[0] < 1.42 - 0.3 and abs(place.qpos[1] - 1.0) < 0.15


def test_s1_grabs_the_basket_by_the_outer_faces_of_its_walls_near_the_robot(s1_plan):
    """Both hands on the outside of the side walls (a point estimated inside the 1 cm wall went to
    its inner face before session 52), in the half nearer the robot (the fixture: 6 cm from the near
    edge), so the upper arms do not lie along the basket."""
    basket = next(o for o in s1_plan.state.objects if o.id == "basket")
    grab = s1_plan.keyframes[2]
    hands = {c.limb: c for c in grab.contacts if c.limb.endswith("hand")}
    assert {c.object_id for c in hands.values()} == {"basket"}
    for limb, side in (("left_hand", 1.0), ("right_hand", -1.0)):
        c = hands[limb]
        offset = np.asarray(c.position) - np.asarray(basket.position)
        assert np.allclose(c.normal, [0.0, side, 0.0], atol=1e-6)        # outward, away from the basket
        assert side * offset[1] > 0.199                                   # on the outer face (y +- 0.2)
        assert -0.13 < offset[0] < -0.03                                  # near half (the robot at -x)


def test_s1_carry_nominal_turns_the_base_with_the_feet(s1_plan):
    """The TO's walking nominal (its walking cost's reference) follows the footholds' headings from
    the planner's footsteps: over S1's carry the base faces where its feet point and stands over
    them (session 52: the route nominal turned 0.5 rad behind the feet and stood 18 cm behind
    them)."""
    from lomanip_to.discretize import ProblemData
    from lomanip_to.problem import WALKING
    from lomanip_to.solver import default_model

    prob = s1_plan.problem
    assert all(c.heading is not None for ph in prob.phases for f, c in ph.contacts.items() if f.endswith("foot"))
    data = ProblemData(prob, default_model())
    X = data._keyframe_nominal()
    walk = [k for k in range(data.grid.K) if prob.phases[data.grid.phase[k]].phase_type == WALKING
            and prob.phases[data.grid.phase[k]].subtask_index == 1
            and X[k, 2] > 0.75]    # upright (the place squat's pelvis offset blends in at the end)
    assert len(walk) > 20
    for k in walk:
        mid, heading = data._feet_at(float(data.grid.t[k]))
        assert abs(np.remainder(X[k, 5] - heading + np.pi, 2 * np.pi) - np.pi) < 0.05
        assert np.linalg.norm(X[k, :2] - mid) < 0.05
