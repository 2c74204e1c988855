"""Contact schedule generation: footsteps, grasp/carry/place, step onto the box, push."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_planner.retargeting import LimbTarget
from lomanip_planner.schedule import ScheduleError, Stance, SubtaskKeyframe, Timing, actions_of, plan_schedule
from lomanip_sim.robot_model import G1_STAND_QPOS
from lomanip_to.problem import FLOOR, WALKING, PlacementGoal, Primitive, Problem, SceneObject, validate_problem


def _feet(x, z=0.0, surface="floor"):
    return [LimbTarget("left_foot", np.array([x, 0.12, z]), object_id=surface),
            LimbTarget("right_foot", np.array([x, -0.12, z]), object_id=surface)]


def _hands(x, z, obj, half=0.2):
    return [LimbTarget("left_hand", np.array([x, half, z]), np.array([0, 1.0, 0]), obj),
            LimbTarget("right_hand", np.array([x, -half, z]), np.array([0, -1.0, 0]), obj)]


def _s1_subtasks():
    q = G1_STAND_QPOS.copy()
    return [SubtaskKeyframe(0, "pick up the box", q, _feet(0.0) + _hands(0.42, 0.15, "box")),
            SubtaskKeyframe(1, "place the box next to the shelf", q, _feet(0.45) + _hands(0.87, 0.15, "box"),
                            placement=PlacementGoal("box", (0.87, 0.0, 0.15), 0.0)),
            SubtaskKeyframe(2, "step on the box and grab the basket", q,
                            _feet(0.87, 0.30, "box") + [LimbTarget("right_hand", np.array([1.2, -0.05, 1.6]),
                                                                   np.array([-1.0, 0, 0]), "basket")])]


def _objects():
    return [SceneObject("box", "box", True, (0.42, 0.0, 0.15), mass=2.5, primitives=[Primitive("box", (0.4, 0.4, 0.3))]),
            SceneObject("basket", "basket", True, (1.3, 0.0, 1.6), mass=0.5, primitives=[Primitive("box", (0.3, 0.4, 0.25))])]


def test_prompt_actions():
    assert actions_of("step on the box and grab the basket") == ["step_on", "pick"]
    assert actions_of("Place the box on the trolley") == ["place"]
    assert actions_of("push the trolley forward") == ["push"]
    assert actions_of("dance") == []


def test_s1_schedule_is_valid_for_the_to():
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, _s1_subtasks(), Timing())
    phases = sched.phases
    assert phases[0].start == 0.0 and all(a.end == pytest.approx(b.start) for a, b in zip(phases, phases[1:]))
    # Single support while walking, the box is free only while held; set down, it rests on the
    # floor (supported) to the end of the placing subtask.
    for ph in phases:
        feet = [l for l in ph.contacts if l.endswith("foot")]
        assert len(feet) == (1 if ph.phase_type == WALKING else 2)
        if "box" in ph.objects and ph.objects["box"].mode == "free":
            assert {"left_hand", "right_hand"} <= set(ph.contacts)
    after = [ph for ph in phases if ph.subtask_index == 1 and ph.start >= sched.placement_goals[0].time - 1e-9]
    assert after and all(ph.objects["box"].mode == "supported" and ph.objects["box"].support == FLOOR for ph in after)
    assert any("left_hand" in ph.contacts for ph in after) and "left_hand" not in after[-1].contacts
    walking_with_box = [ph for ph in phases if ph.phase_type == WALKING and "box" in ph.objects]
    assert walking_with_box and all(ph.subtask_index == 1 for ph in walking_with_box)
    last = phases[-1]
    assert last.contacts["left_foot"].object_id == "box" and last.contacts["right_foot"].object_id == "box"
    assert not any("box" in ph.objects for ph in phases if ph.subtask_index == 2)
    # Keyframes at increasing times inside their subtask; the placement goal is timed.
    times = [k.time for k in sched.keyframes]
    assert times == sorted(times) and len(times) == 3
    assert sched.placement_goals[0].object_id == "box" and sched.placement_goals[0].time == pytest.approx(times[1])
    # Steps are at most max_step_length.
    validate_problem(Problem(objects=_objects(), keyframes=sched.keyframes, phases=phases,
                             initial_configuration=tuple([0, 0, 0.79, 0, 0, 0] + [0.0] * 29),
                             placement_goals=sched.placement_goals))


def test_push_makes_a_rolling_object_move_while_walking():
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    goal = PlacementGoal("trolley", (1.4, 0.0, 0.3), 0.0)
    push = SubtaskKeyframe(0, "push the trolley forward", G1_STAND_QPOS.copy(),
                           _feet(0.6) + _hands(0.5, 0.85, "trolley", half=0.2), rolling_objects=frozenset({"trolley"}),
                           placement=goal, push_feet=_feet(1.1))
    sched = plan_schedule(stance, [push])
    moving = [ph for ph in sched.phases if "trolley" in ph.objects]
    assert moving and all(ph.objects["trolley"].mode == "rolling" for ph in moving)
    assert any(ph.phase_type == WALKING for ph in moving)
    # first the robot walks up to the handle with the trolley still, then grasps, then pushes
    first_move = sched.phases.index(moving[0])
    assert any(ph.phase_type == WALKING for ph in sched.phases[:first_move])
    assert sched.keyframes[0].time <= moving[0].start + 1e-9
    # the push ends where the goal holds, the feet 0.5 m further on
    g = sched.placement_goals[0]
    assert g.object_id == "trolley" and g.time == pytest.approx(moving[-1].end)


def test_an_object_placed_on_the_trolley_rests_on_it_then_rides_on_it_during_the_push():
    """Set down on the deck (a lower primitive than the trolley's handle) the box stays where it
    was put (static, as in the S2 fixture) and rides on the trolley while it is pushed."""
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    trolley = SceneObject("trolley", "trolley", True, (1.0, 0.0, 0.0), mass=10.0,
                          primitives=[Primitive("box", (0.6, 0.4, 0.1), position=(0.0, 0.0, 0.45)),
                                      Primitive("box", (0.03, 0.4, 0.03), position=(-0.3, 0.0, 0.9))])  # the handle
    box = SceneObject("box", "box", True, (0.42, 0.0, 0.15), mass=2.5, primitives=[Primitive("box", (0.3, 0.3, 0.3))])
    q = G1_STAND_QPOS.copy()
    on_deck = (1.0, 0.0, 0.5 + 0.15)        # deck top 0.5 m, box half height 0.15 m
    subtasks = [SubtaskKeyframe(0, "pick up the box", q, _feet(0.0) + _hands(0.42, 0.15, "box", half=0.15)),
                SubtaskKeyframe(1, "place the box on the trolley", q, _feet(0.55) + _hands(1.0, 0.65, "box", half=0.15),
                                placement=PlacementGoal("box", on_deck, 0.0)),
                SubtaskKeyframe(2, "push the trolley forward", q, _feet(0.55) + _hands(0.75, 0.8, "trolley"),
                                rolling_objects=frozenset({"trolley"}), push_feet=_feet(1.05),
                                placement=PlacementGoal("trolley", (1.5, 0.0, 0.0), 0.0))]
    sched = plan_schedule(stance, subtasks, objects=[box, trolley])
    place_t = next(g.time for g in sched.placement_goals if g.object_id == "box")
    after = [ph for ph in sched.phases if ph.start >= place_t - 1e-9 and "trolley" not in ph.objects]
    assert after and all("box" not in ph.objects for ph in after)   # static from the place on
    pushing = [ph for ph in sched.phases if "trolley" in ph.objects]
    assert pushing and all(ph.objects["box"].mode == "attached" and ph.objects["box"].attached_to == "trolley"
                           for ph in pushing)
    # placed beside the trolley instead, it rests on the floor
    beside = subtasks[:1] + [SubtaskKeyframe(1, "place the box on the floor", q, _feet(0.0) + _hands(0.42, 0.15, "box", half=0.15),
                                             placement=PlacementGoal("box", (0.0, 0.6, 0.15), 0.0))]
    last = [ph.objects["box"] for ph in plan_schedule(stance, beside, objects=[box, trolley]).phases if "box" in ph.objects]
    assert last[-1].mode == "supported" and last[-1].support == FLOOR


def test_placing_nothing_is_an_error():
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    with pytest.raises(ScheduleError, match="nothing is held"):
        plan_schedule(stance, [SubtaskKeyframe(0, "place the box", G1_STAND_QPOS.copy(), _feet(0.0),
                                               placement=PlacementGoal("box", (1, 0, 0.15), 0.0))])


def test_steps_follow_the_horizontal_distance_and_the_lift_opens_the_next_subtask():
    """As in the hand-written fixtures: the pick's keyframe is the grasp (box at rest), the lift is the
    first phase of the carry; a step up onto the box is one (longer) step of each foot."""
    tm = Timing()
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, _s1_subtasks(), tm)
    ph = sched.phases
    kf_pick = sched.keyframes[0].time
    at_pick = [p for p in ph if p.end <= kf_pick + 1e-9]
    assert at_pick[-1].subtask_index == 0 and "box" not in at_pick[-1].objects
    assert {"left_hand", "right_hand"} <= set(at_pick[-1].contacts)
    first_carry = next(p for p in ph if p.subtask_index == 1)
    assert first_carry.start == pytest.approx(kf_pick) and first_carry.objects["box"].mode == "free"
    assert first_carry.phase_type != WALKING
    # subtask 2: 0.42 m onto the box -> 2 steps per foot at 0.35 m, the last of each onto the box
    steps = [p for p in ph if p.subtask_index == 2 and p.phase_type == WALKING]
    assert len(steps) == 4
    assert [p.end - p.start for p in steps] == pytest.approx([tm.step, tm.step, tm.step_up, tm.step_up])
    # without the scene's objects there is no pose to lift the grabbed basket from: it never moves
    assert not any("basket" in p.objects for p in ph)


def test_the_last_grab_lifts_its_object_and_holds_it():
    tm = Timing()
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, _s1_subtasks(), tm, objects=_objects())
    ph = sched.phases
    kf_grab = sched.keyframes[2].time
    assert not any("basket" in p.objects for p in ph if p.end <= kf_grab + 1e-9)
    after = [p for p in ph if p.start >= kf_grab - 1e-9]
    assert after and all(p.objects["basket"].mode == "free" and "right_hand" in p.contacts for p in after)
    goal = next(g for g in sched.placement_goals if g.object_id == "basket")
    assert goal.time == pytest.approx(kf_grab + tm.manipulate)
    assert goal.position == pytest.approx((1.3, 0.0, 1.6 + tm.final_lift))
    assert ph[-1].end - goal.time >= tm.retract - 1e-9   # held there to the end


def test_a_last_grab_without_a_final_lift_ends_holding_it():
    from dataclasses import replace

    tm = replace(Timing(), final_lift=0.0)
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, _s1_subtasks(), tm, objects=_objects())
    assert not any("basket" in p.objects for p in sched.phases)
    assert not any(g.object_id == "basket" for g in sched.placement_goals)


def test_a_long_carry_off_the_heading_walks_forwards():
    """A carry 1.3 m away at 50 degrees off the robot's heading (S1's): the intermediate footholds
    lie either side of the route across the turned heading (walking forwards), not side-stepping
    along the straight line between the stances with the feet across the start heading."""
    import math

    from lomanip_to.route import walking_heading

    q = G1_STAND_QPOS.copy()
    subtasks = [SubtaskKeyframe(0, "pick up the box", q, _feet(0.0) + _hands(0.42, 0.15, "box")),
                SubtaskKeyframe(1, "place the box next to the shelf", q,
                                [LimbTarget(f, np.array([0.85, 1.0 + y, 0.0]), object_id="floor")
                                 for f, y in (("left_foot", 0.12), ("right_foot", -0.12))] + _hands(1.27, 0.15, "box", ),
                                placement=PlacementGoal("box", (1.27, 1.0, 0.15), 0.0))]
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, subtasks, Timing())
    carry = [ph for ph in sched.phases if ph.subtask_index == 1 and ph.phase_type != WALKING
             and {"left_foot", "right_foot"} <= set(ph.contacts)]
    pairs = []
    for ph in carry:
        pair = (tuple(ph.contacts["left_foot"].position[:2]), tuple(ph.contacts["right_foot"].position[:2]))
        if not pairs or pairs[-1] != pair:
            pairs.append(pair)
    # the middle double stances: the feet's line is across a heading turned towards the travel
    # direction (atan2(1.0, 0.85) = 0.87 rad), not across the start heading (0)
    mid = pairs[len(pairs) // 2]
    lat = np.subtract(mid[0], mid[1])
    heading = math.atan2(lat[1], lat[0]) - math.pi / 2
    assert heading > 0.5
    assert abs(heading - math.atan2(1.0, 0.85)) < 0.35
    # the first and last stances are the keyframes' (facing +x)
    assert pairs[0][0][1] - pairs[0][1][1] == pytest.approx(0.24, abs=1e-6)
    assert pairs[-1][0] == pytest.approx((0.85, 1.12)) and pairs[-1][1] == pytest.approx((0.85, 0.88))
    assert walking_heading(np.array([[0.0, 0.0], [0.85, 1.0]]), 0.5, 0.0, 0.0) > 0.5


def test_a_last_grab_lifts_an_object_from_where_the_plan_placed_it():
    q = G1_STAND_QPOS.copy()
    subtasks = [SubtaskKeyframe(0, "pick up the box", q, _feet(0.0) + _hands(0.42, 0.15, "box")),
                SubtaskKeyframe(1, "place the box", q, _feet(0.45) + _hands(0.87, 0.15, "box"),
                                placement=PlacementGoal("box", (0.87, 0.0, 0.15), 0.3)),
                SubtaskKeyframe(2, "grab the box", q, _feet(0.45) + _hands(0.87, 0.15, "box"))]
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, subtasks, Timing(), objects=_objects())
    goal = sched.placement_goals[-1]
    assert goal.object_id == "box" and goal.time > sched.placement_goals[0].time
    assert goal.position == pytest.approx((0.87, 0.0, 0.15 + Timing().final_lift))   # not its start (0.42)
    assert goal.yaw == pytest.approx(0.3)


def test_a_floor_step_towards_a_box_to_step_onto_stays_off_its_footprint():
    # the feet end the placing subtask 0.42 m behind the placed box's centre (its near face 0.22 m
    # ahead of them): longer than a step, so one floor step comes before the step up; it must keep
    # the sole off the box (FOOTHOLD_CLEARANCE), not land halfway, under the box's edge
    from lomanip_planner.schedule import FOOTHOLD_CLEARANCE

    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    sched = plan_schedule(stance, _s1_subtasks(), Timing(), objects=_objects())
    near_face = 0.87 - 0.2
    floor_steps = [c.position for ph in sched.phases if ph.subtask_index == 2
                   for limb, c in ph.contacts.items() if limb.endswith("foot") and c.object_id == FLOOR]
    assert len({tuple(np.round(p, 3)) for p in floor_steps}) > 2   # it does step on the floor first
    assert max(p[0] for p in floor_steps) <= near_face - FOOTHOLD_CLEARANCE + 1e-6
    on_box = sched.phases[-1].contacts
    assert on_box["left_foot"].object_id == "box" and on_box["right_foot"].object_id == "box"


def test_a_reach_above_the_shoulders_takes_longer():
    from dataclasses import replace

    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))

    def grab_reach(tm):
        sched = plan_schedule(stance, _s1_subtasks(), tm, objects=_objects())
        grab = sched.keyframes[2].time - tm.grasp   # the reach ends where the grasp starts
        return next(p for p in sched.phases if abs(p.end - grab) < 1e-9 and p.subtask_index == 2)

    tm = Timing()
    reach = grab_reach(tm)
    # the basket's hand target 1.6 m up, the soles on the 0.3 m box: 0.3 m above the shoulders
    rise = 1.6 - 0.30 - tm.reach_shoulder_height
    assert reach.end - reach.start == pytest.approx(tm.reach + rise / tm.reach_overhead_speed)
    off = replace(tm, reach_overhead_speed=0.0)
    assert grab_reach(off).end - grab_reach(off).start == pytest.approx(tm.reach)
    # the pick of the box (hands 0.15 m up) keeps the plain reach
    first = plan_schedule(stance, _s1_subtasks(), tm, objects=_objects())
    pick = first.keyframes[0].time - tm.grasp
    assert any(abs(p.end - pick) < 1e-9 and abs(p.end - p.start - tm.reach) < 1e-9 for p in first.phases)
