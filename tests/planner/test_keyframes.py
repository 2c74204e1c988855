"""Perception output -> retargeted keyframes -> schedule -> a valid TO problem, on S1's geometry."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_planner.keyframes import SubtaskPerception, build_problem, retarget_subtasks
from lomanip_planner.retargeting import LimbTarget, Retargeter, RetargetingError
from lomanip_planner.schedule import Stance
from lomanip_sim import frames
from lomanip_to.problem import PlacementGoal, Primitive, SceneObject, validate_problem

# S1 defaults of lomanip_sim (scenarios.yaml): box 0.4 x 0.4 x 0.3 at (0.7, 0); shelf top 1.5 m with
# its front face at x = 1.7; basket 0.3 x 0.4 x 0.25 on it, front wall 3 cm behind the edge.
OBJECTS = [
    SceneObject("box", "box", True, (0.70, 0.0, 0.15), mass=2.5, primitives=[Primitive("box", (0.4, 0.4, 0.3))]),
    SceneObject("shelf", "shelf", False, (1.90, 1.0, 0.75), primitives=[Primitive("box", (0.4, 0.8, 1.5))]),
    SceneObject("basket", "basket", True, (1.88, 1.0, 1.625), mass=0.5, primitives=[Primitive("box", (0.3, 0.4, 0.25))]),
]


def _s1_perception():
    n = lambda *v: np.array(v, float)  # noqa: E731
    return [
        SubtaskPerception(0, "pick up the box", [
            LimbTarget("left_foot", n(0.32, 0.12, 0.0)), LimbTarget("right_foot", n(0.32, -0.12, 0.0)),
            LimbTarget("left_hand", n(0.70, 0.2, 0.22), n(0, 1, 0), "box"),
            LimbTarget("right_hand", n(0.70, -0.2, 0.22), n(0, -1, 0), "box")]),
        # Perception sees the box where it is now (0.7, 0); the keyframes move these contacts with
        # the box to its placement goal (1.48, 1.0).
        SubtaskPerception(1, "place the box next to the shelf", [
            LimbTarget("left_foot", n(0.32, 0.12, 0.0)), LimbTarget("right_foot", n(0.32, -0.12, 0.0)),
            LimbTarget("left_hand", n(0.70, 0.2, 0.22), n(0, 1, 0), "box"),
            LimbTarget("right_hand", n(0.70, -0.2, 0.22), n(0, -1, 0), "box")]),
        SubtaskPerception(2, "step on the box and grab the basket", [
            LimbTarget("left_foot", n(0.72, 0.1, 0.0), object_id="box"),
            LimbTarget("right_foot", n(0.72, -0.1, 0.0), object_id="box"),
            LimbTarget("right_hand", n(1.73, 0.92, 1.68), n(-1, 0, 0), "basket")]),
    ]


def test_s1_from_perception_to_a_valid_to_problem():
    retargeter = Retargeter()
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    placements = {"box": PlacementGoal("box", (1.48, 1.0, 0.15), 0.0)}
    # The box gets placed before the robot steps on it: its top is at its placed height.
    objects = {o.id: o for o in OBJECTS}
    kfs = retarget_subtasks(_s1_perception(), OBJECTS, stance, retargeter, placements)
    assert len(kfs) == 3
    feet = [c.position for c in kfs[2].contacts if c.limb.endswith("foot")]
    assert [p[2] for p in feet] == pytest.approx([0.30, 0.30])   # foot height set by the task (box top)
    assert [p[0] for p in feet] == pytest.approx([1.50, 1.50])   # on the box where it was placed
    hands = [c.position for c in kfs[1].contacts if c.limb.endswith("hand")]
    assert np.mean(hands, axis=0)[:2] == pytest.approx([1.48, 1.0], abs=1e-9)  # placing: hands at the goal
    for kf in kfs:                                                # the acceptance bounds of issue 5
        r = kf.retarget
        assert max(r.residuals.values()) <= 0.01 and r.within_joint_limits and r.min_self_distance >= 0.0
        assert max(r.foot_tilt.values()) < 0.02
    x0 = [0, 0, 0.79, 0, 0, 0] + [0.0] * 29
    problem, schedule = build_problem(OBJECTS, kfs, stance, x0, name="s1_basket")
    validate_problem(problem)
    assert [k.subtask_index for k in problem.keyframes] == [0, 1, 2]
    assert schedule.placement_goals[0].object_id == "box"
    assert objects["box"].movable


def test_hand_on_an_unknown_object_is_reported():
    bad = _s1_perception()[:1]
    bad[0].contacts[2] = LimbTarget("left_hand", np.array([0.7, 0.2, 0.2]), np.array([0, 1.0, 0]), "refrigerator")
    with pytest.raises(RetargetingError, match="refrigerator"):
        retarget_subtasks(bad, OBJECTS, Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0])), Retargeter())


def test_s1_carried_box_nominal_is_set_down_at_its_goal_not_under_the_floor():
    """The TO's nominal for the generated S1: the carry's blend ends at the knot where the box is set
    down, not where the robot has stood up again (before: the box went 0.3 m under the floor before
    its placement, and the warm start's IK rolled the base 0.6 rad reaching for it)."""
    from lomanip_to.discretize import ProblemData
    from lomanip_to.solver import default_model

    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    placements = {"box": PlacementGoal("box", (1.48, 1.0, 0.15), 0.0)}
    kfs = retarget_subtasks(_s1_perception(), OBJECTS, stance, Retargeter(), placements)
    x0 = [0, 0, 0.79, 0, 0, 0] + [0.0] * 29
    problem, _ = build_problem(OBJECTS, kfs, stance, x0, name="s1_basket")
    data = ProblemData(problem, default_model())
    box = data.obj_nom["box"]
    modes = [data.obj_mode(k, "box") for k in range(data.grid.K)]
    assert box[:, 2].min() > 0.15 - 1e-4, f"box nominal at {box[:, 2].min():.2f} m"
    k_set = [k for k in range(1, data.grid.K) if modes[k - 1] == "free" and modes[k] == "supported"]
    assert len(k_set) == 1
    np.testing.assert_allclose(box[k_set[0], :3], (1.48, 1.0, 0.15), atol=1e-6)
    walking = [k for k in range(data.grid.K)
               if modes[k] == "free" and data.prob.phases[data.grid.phase[k]].phase_type == "walking"]
    assert walking and np.median(box[walking, 2]) > 0.5   # carried, not dragged along the floor


def _heavy_pick(retargeter: Retargeter, monkeypatch, margin: float | None):
    """A 10 kg crate picked at arm's length from the person's stance, with the balance step at ``margin``."""
    from lomanip_planner import keyframes

    monkeypatch.setattr(keyframes, "LOAD_BALANCE_MARGIN", margin)
    n = lambda *v: np.array(v, float)  # noqa: E731
    crate = SceneObject("crate", "box", True, (0.62, 0.0, 0.85), mass=10.0, primitives=[Primitive("box", (0.3, 0.3, 0.3))])
    st = SubtaskPerception(0, "pick up the crate", [
        LimbTarget("left_foot", n(0.0, 0.12, 0.0)), LimbTarget("right_foot", n(0.0, -0.12, 0.0)),
        LimbTarget("left_hand", n(0.62, 0.15, 0.85), n(0, 1, 0), "crate"),
        LimbTarget("right_hand", n(0.62, -0.15, 0.85), n(0, -1, 0), "crate")])
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    return retarget_subtasks([st], [crate], stance, retargeter)[0]


def test_a_pick_at_arms_length_balances_the_load_over_the_feet(monkeypatch):
    from lomanip_planner.keyframes import LOAD_BALANCE_MARGIN

    retargeter = Retargeter()
    unbalanced = _heavy_pick(retargeter, monkeypatch, None).load_balance
    assert unbalanced.mass == 10.0 and unbalanced.margin_after == unbalanced.margin_before < LOAD_BALANCE_MARGIN
    kf = _heavy_pick(retargeter, monkeypatch, LOAD_BALANCE_MARGIN)
    assert kf.load_balance.margin_before == pytest.approx(unbalanced.margin_before)
    assert kf.load_balance.margin_after >= LOAD_BALANCE_MARGIN - 1e-3
    r = kf.retarget
    assert max(r.residuals.values()) <= 0.01 and r.within_joint_limits and r.min_self_distance >= 0.0
    feet = [c.position for c in kf.contacts if c.limb.endswith("foot")]
    np.testing.assert_allclose([p[:2] for p in feet], [[0.0, 0.12], [0.0, -0.12]] + kf.load_balance.shift, atol=1e-9)
    assert [p[2] for p in feet] == [0.0, 0.0]


def test_feet_on_a_top_step_only_as_far_as_their_soles_stay_on_it():
    from lomanip_planner.keyframes import TOP_EDGE_MARGIN, _step_room
    from lomanip_to.model import SOLE_CORNERS
    from lomanip_to.route import Footprint

    retargeter = Retargeter()
    retargeter.configuration.update(retargeter.stand)   # level feet, ankles at x = 0
    ankle_x = retargeter.configuration.data.xpos[retargeter.model.body("left_ankle_roll_link").id][0]
    toe = ankle_x + SOLE_CORNERS[:, 0].max()
    top = Footprint((0.05, 0.0), 0.0, (0.2, 0.2), "crate")
    assert _step_room(retargeter, np.array([0.3, 0.0, 0.0]), None) == 1.0
    assert _step_room(retargeter, np.array([0.3, 0.0, 0.0]), top) == pytest.approx((0.25 - TOP_EDGE_MARGIN - toe) / 0.3)
    assert _step_room(retargeter, np.array([0.01, 0.0, 0.0]), top) == 1.0
    assert _step_room(retargeter, np.array([0.1, 0.0, 0.0]), Footprint((0.3, 0.0), 0.0, (0.2, 0.2), "crate")) == 0.0


def test_a_picked_squeeze_is_antipodal_through_the_com_and_the_place_keeps_it(monkeypatch):
    """With ``ANTIPODAL_SQUEEZE`` on, the transferred hands 9 cm apart along the box's faces and 4 cm
    apart in height become one grasp line through the box's CoM, level at their mean height; the
    place holds the box the same way."""
    from lomanip_planner import keyframes

    monkeypatch.setattr(keyframes, "ANTIPODAL_SQUEEZE", True)
    perceived = _s1_perception()[:2]
    n = lambda *v: np.array(v, float)  # noqa: E731
    for st in perceived:
        st.contacts[2] = LimbTarget("left_hand", n(0.65, 0.2, 0.24), n(0, 1, 0), "box")
        st.contacts[3] = LimbTarget("right_hand", n(0.74, -0.2, 0.20), n(0, -1, 0), "box")
    stance = Stance(np.array([0.0, 0.12, 0.0]), np.array([0.0, -0.12, 0.0]))
    placements = {"box": PlacementGoal("box", (1.48, 1.0, 0.15), 0.0)}
    kfs = retarget_subtasks(perceived, OBJECTS, stance, Retargeter(), placements)
    for kf, centre in zip(kfs, ((0.70, 0.0, 0.15), (1.48, 1.0, 0.15))):
        hands = {c.limb: c.position - np.asarray(centre) for c in kf.contacts if c.limb.endswith("hand")}
        np.testing.assert_allclose(hands["left_hand"], (0.0, 0.2, 0.07), atol=1e-9)
        np.testing.assert_allclose(hands["right_hand"], (0.0, -0.2, 0.07), atol=1e-9)
        assert max(kf.retarget.residuals.values()) <= 0.01
