"""From perception output to keyframes and a TO problem (paper Sec. III-A3 and IV-B).

Per subtask, perception gives the transferred contacts L (limb, object, point, normal) and the human
pose (pelvis orientation after the rigid transfer, joint angles mapped onto the G1). Here:

* foot targets: the transferred xy of each foot; the height is set by the task, i.e. by the
  surface the foot stands on (the floor, or the top of the object it touches, as in S1's box);
  a foot without a contact keeps its current position;
* hand targets: the transferred points and normals;
* the human pelvis orientation and joint angles go into the IK as base orientation and posture prior;
* the desired mid-foot position of eq. (2) is the keyframe's mid-foot point, referred to the object
  the hands touch.

Then :func:`build_problem` assembles scene, keyframes, schedule and options into the TO's problem.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lomanip_to.problem import FLOOR, Options, PlacementGoal, Problem, SceneObject

from .retargeting import FEET, HANDS, LimbTarget, RetargetTarget, Retargeter, RetargetingError
from .schedule import Schedule, Stance, SubtaskKeyframe, Timing, plan_schedule


@dataclass
class SubtaskPerception:
    """What perception extracted for one subtask (world frame)."""

    index: int
    prompt: str
    contacts: list[LimbTarget]
    base_orientation_wxyz: np.ndarray | None = None
    joint_prior: dict[str, float] = field(default_factory=dict)


def surface_height(object_id: str, objects: dict[str, SceneObject]) -> float:
    """World height of the top of what a foot stands on."""
    if object_id in ("", FLOOR):
        return 0.0
    if object_id not in objects:
        raise RetargetingError(-2, f"foot contact on unknown object {object_id!r}")
    o = objects[object_id]
    return float(o.position[2] + o.top_z())


def retarget_subtasks(subtasks: list[SubtaskPerception], objects: list[SceneObject], stance: Stance,
                      retargeter: Retargeter, placements: dict[str, PlacementGoal] | None = None,
                      current_qpos: np.ndarray | None = None) -> list[SubtaskKeyframe]:
    """One retargeted keyframe per subtask, chained (each starts from the previous solution)."""
    by_id = {o.id: o for o in objects}
    placements = placements or {}
    feet_now = {"left_foot": (stance.left.copy(), stance.left_surface),
                "right_foot": (stance.right.copy(), stance.right_surface)}
    out: list[SubtaskKeyframe] = []
    q = current_qpos
    for st in subtasks:
        targets: list[LimbTarget] = []
        given = {c.limb: c for c in st.contacts}
        for limb in FEET:
            if limb in given:
                c = given[limb]
                p = np.array([c.position[0], c.position[1], surface_height(c.object_id, by_id)])
                feet_now[limb] = (p, c.object_id or FLOOR)
            p, surface = feet_now[limb]
            targets.append(LimbTarget(limb, p.copy(), np.array([0.0, 0.0, 1.0]), surface))
        for limb in HANDS:
            if limb in given:
                c = given[limb]
                if c.object_id not in by_id:
                    raise RetargetingError(-2, f"subtask {st.index}: {limb} touches unknown object {c.object_id!r}")
                targets.append(LimbTarget(limb, np.asarray(c.position, float), np.asarray(c.normal, float), c.object_id))
        try:
            res = retargeter.solve(RetargetTarget(tuple(targets), st.base_orientation_wxyz, st.joint_prior), q)
        except RetargetingError as exc:
            raise RetargetingError(exc.code, f"subtask {st.index} ({st.prompt!r}): {exc}") from exc
        q = res.qpos
        hand_objects = [t.object_id for t in targets if t.limb in HANDS]
        rolling = frozenset(o.id for o in objects if o.object_class == "trolley")
        placement = next((placements[oid] for oid in hand_objects if oid in placements), None)
        out.append(SubtaskKeyframe(st.index, st.prompt, res.qpos, targets, rolling_objects=rolling,
                                   placement=placement, reference_object_id=hand_objects[0] if hand_objects else ""))
    return out


def build_problem(objects: list[SceneObject], keyframes: list[SubtaskKeyframe], stance: Stance,
                  initial_configuration: tuple, options: Options | None = None, timing: Timing = Timing(),
                  name: str = "") -> tuple[Problem, Schedule]:
    """The TO problem for a keyframe sequence (schedule generated between the keyframes)."""
    schedule = plan_schedule(stance, keyframes, timing)
    problem = Problem(objects=list(objects), keyframes=schedule.keyframes, phases=schedule.phases,
                      initial_configuration=tuple(initial_configuration),
                      placement_goals=schedule.placement_goals, options=options or Options(), name=name)
    return problem, schedule
