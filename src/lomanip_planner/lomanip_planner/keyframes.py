"""From perception output to keyframes and a TO problem (paper Sec. III-A3 and IV-B).

Per subtask, perception gives the transferred contacts L (limb, object, point, normal) and the human
pose (pelvis orientation after the rigid transfer, joint angles mapped onto the G1). Here:

* foot targets: the transferred xy of each foot; the height is set by the task, i.e. by the
  surface the foot stands on (the floor, or the top of the object it touches, as in S1's box);
  a foot without a contact keeps its current position;
* hand targets: the transferred points and normals;
* the human pelvis orientation and joint angles go into the IK as base orientation and posture prior;
* the desired mid-foot position of eq. (2) is the keyframe's mid-foot point, referred to the object
  the hands touch;
* perception sees every object where it is now, but earlier subtasks may move it: a subtask whose
  hands hold an object with a placement goal is keyframed at the goal (its contacts and floor feet
  moved rigidly with the object), and later contacts on a moved object move with it
  (:class:`_Displacement`).

Then :func:`build_problem` assembles scene, keyframes, schedule and options into the TO's problem.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from lomanip_to.problem import FLOOR, Options, PlacementGoal, Problem, SceneObject

from .retargeting import FEET, HANDS, LimbTarget, RetargetTarget, Retargeter, RetargetingError
from .schedule import Schedule, actions_of, Stance, SubtaskKeyframe, Timing, plan_schedule


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


def x_from_qpos(qpos: np.ndarray) -> tuple:
    """The TO's 35-D state (base position, roll-pitch-yaw, 29 joints) of a MuJoCo-order qpos."""
    from lomanip_sim import frames

    return (*qpos[:3], *frames.quat_to_rpy(qpos[3:7]), *qpos[7:])


def stance_from_qpos(retargeter: Retargeter, qpos: np.ndarray, surfaces=(FLOOR, FLOOR)) -> Stance:
    """Sole centres of both feet for a configuration (forward kinematics of the shared model)."""
    import mujoco

    data = mujoco.MjData(retargeter.model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(retargeter.model, data)
    sole = np.array([0.0, 0.0, retargeter.sole_offset])
    return Stance(data.site("left_foot").xpos - sole, data.site("right_foot").xpos - sole, *surfaces)


@dataclass(frozen=True)
class _Displacement:
    """Planar rigid motion of an object from where perception saw it to where the plan puts it."""

    origin: np.ndarray   # object position when perceived
    target: np.ndarray   # its planned position
    dyaw: float

    @staticmethod
    def of(obj: SceneObject, goal: PlacementGoal) -> "_Displacement":
        return _Displacement(np.asarray(obj.position, float), np.asarray(goal.position, float),
                             float(goal.yaw) - obj.yaw())

    def _R(self) -> np.ndarray:
        c, s = np.cos(self.dyaw), np.sin(self.dyaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def point(self, p: np.ndarray) -> np.ndarray:
        return self.target + self._R() @ (np.asarray(p, float) - self.origin)

    def normal(self, n: np.ndarray) -> np.ndarray:
        return self._R() @ np.asarray(n, float)

    def moved(self, t: LimbTarget) -> LimbTarget:
        return LimbTarget(t.limb, self.point(t.position), self.normal(t.normal), t.object_id)


#: how far "push X forward" moves X when the request gives no placement goal for it (m): one step of
#: each foot (schedule.Timing.max_step_length); the planner node's ``push_distance`` parameter
PUSH_DISTANCE = 0.25


def _as_placed(obj: SceneObject, d: "_Displacement | None") -> SceneObject:
    """The object where the plan has it so far (after earlier subtasks moved it)."""
    if d is None:
        return obj
    from lomanip_sim import frames as fr

    yaw = obj.yaw() + d.dyaw
    q = fr.yaw_to_quat(yaw)   # (w, x, y, z)
    return replace(obj, position=tuple(d.target), quat_xyzw=(q[1], q[2], q[3], q[0]))


def push_goal(obj: SceneObject, d: "_Displacement | None" = None, distance: float = PUSH_DISTANCE) -> PlacementGoal:
    """Where "push X forward" takes X: ``distance`` along its heading (local +x), same yaw."""
    o = _as_placed(obj, d)
    yaw = o.yaw()
    p = np.asarray(o.position, float) + distance * np.array([np.cos(yaw), np.sin(yaw), 0.0])
    return PlacementGoal(o.id, tuple(float(v) for v in p), float(yaw))


def retarget_subtasks(subtasks: list[SubtaskPerception], objects: list[SceneObject], stance: Stance,
                      retargeter: Retargeter, placements: dict[str, PlacementGoal] | None = None,
                      current_qpos: np.ndarray | None = None,
                      push_distance: float = PUSH_DISTANCE) -> list[SubtaskKeyframe]:
    """One retargeted keyframe per subtask, chained (each starts from the previous solution)."""
    by_id = {o.id: o for o in objects}
    placements = placements or {}
    feet_now = {"left_foot": (stance.left.copy(), stance.left_surface),
                "right_foot": (stance.right.copy(), stance.right_surface)}
    out: list[SubtaskKeyframe] = []
    # The first IK starts from the retargeter's own seeds, not from the measured state: a seed that
    # differs by sensor-level noise can flip which local solution the IK finds (feet kept vs slid),
    # and with it the footsteps of the whole plan. ``current_qpos`` is kept for callers' records.
    q = None
    moved: dict[str, _Displacement] = {}
    for st in subtasks:
        targets: list[LimbTarget] = []
        held = [c.object_id for c in st.contacts if c.limb in HANDS]
        placing = next((oid for oid in held if oid in placements and oid in by_id), None) \
            if "place" in actions_of(st.prompt) else None
        if placing is not None:
            moved[placing] = _Displacement.of(by_id[placing], placements[placing])
        carried = next((moved[oid] for oid in held if oid in moved), None)
        given = {}
        for c in st.contacts:   # perceived where the objects are now; move them to where the plan has them
            d = moved.get(c.object_id) if c.object_id in by_id else carried
            given[c.limb] = d.moved(c) if d is not None else c
        for limb in FEET:
            if limb in given:
                c = given[limb]
                height = surface_height(c.object_id, by_id)
                if c.object_id in moved:
                    height += moved[c.object_id].target[2] - moved[c.object_id].origin[2]
                p = np.array([c.position[0], c.position[1], height])
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
            try:
                res = retargeter.solve(RetargetTarget(tuple(targets), st.base_orientation_wxyz, st.joint_prior), q)
            except RetargetingError:
                # the demonstrator's stance is an adult's: let floor feet slide to where the G1 reaches
                res = retargeter.solve(RetargetTarget(tuple(targets), st.base_orientation_wxyz, st.joint_prior,
                                                      floor_feet_slide=True), q)
                targets = [LimbTarget(t.limb, res.contact_points[t.limb].copy(), t.normal, t.object_id)
                           if t.limb in FEET else t for t in targets]
                for t in targets:
                    if t.limb in FEET:
                        feet_now[t.limb] = (t.position.copy(), t.object_id)
        except RetargetingError as exc:
            raise RetargetingError(exc.code, f"subtask {st.index} ({st.prompt!r}): {exc}") from exc
        q = res.qpos
        hand_objects = [t.object_id for t in targets if t.limb in HANDS]
        rolling = frozenset(o.id for o in objects if o.object_class == "trolley")
        placement = next((placements[oid] for oid in hand_objects if oid in placements), None)
        push_feet = []
        if "push" in actions_of(st.prompt) and hand_objects:
            pushed = by_id[hand_objects[0]]
            if pushed.id not in placements:   # default: straight ahead along the object's heading
                placement = push_goal(pushed, moved.get(pushed.id), push_distance)
            d = _Displacement.of(_as_placed(pushed, moved.get(pushed.id)), placement)
            moved[pushed.id] = _Displacement.of(pushed, placement)
            # the feet walk with the push; later subtasks start from there
            push_feet = [d.moved(t) for t in targets if t.limb in FEET]
            for t in push_feet:
                feet_now[t.limb] = (t.position.copy(), t.object_id)
        out.append(SubtaskKeyframe(st.index, st.prompt, res.qpos, targets, rolling_objects=rolling,
                                   placement=placement, reference_object_id=hand_objects[0] if hand_objects else "",
                                   retarget=res, push_feet=push_feet))
    return out


def build_problem(objects: list[SceneObject], keyframes: list[SubtaskKeyframe], stance: Stance,
                  initial_configuration: tuple, options: Options | None = None, timing: Timing = Timing(),
                  name: str = "") -> tuple[Problem, Schedule]:
    """The TO problem for a keyframe sequence (schedule generated between the keyframes)."""
    schedule = plan_schedule(stance, keyframes, timing, objects=list(objects))
    problem = Problem(objects=list(objects), keyframes=schedule.keyframes, phases=schedule.phases,
                      initial_configuration=tuple(initial_configuration),
                      placement_goals=schedule.placement_goals, options=options or Options(), name=name)
    return problem, schedule
