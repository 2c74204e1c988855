"""From perception output to keyframes and a TO problem (paper Sec. III-A3 and IV-B).

Per subtask, perception gives the transferred contacts L (limb, object, point, normal) and the human
pose (pelvis orientation after the rigid transfer, joint angles mapped onto the G1). Here:

* foot targets: the transferred xy of each foot; the height is set by the task, i.e. by the
  surface the foot stands on (the floor, or the top of the object it touches, as in S1's box);
  a foot without a contact keeps its current position;
* hand targets: the transferred points and normals (optionally, ``ANTIPODAL_SQUEEZE``, a
  two-handed squeeze picked up is made antipodal through the object's CoM: grasp.py);
* the human pelvis orientation and joint angles go into the IK as base orientation and posture prior;
* a keyframe whose hands take up (pick) or hold (place) an object must balance the object's
  weight too: when the robot-and-object CoM is not ``LOAD_BALANCE_MARGIN`` inside the soles, the
  IK is solved again with the load in its CoM task and, if needed, the feet step towards the load
  (on an object's top only as far as they stay on it; :func:`_balance_under_load`, a departure
  from the paper, which takes the feet from the person's stance);
* the desired mid-foot position of eq. (2) is the keyframe's mid-foot point, referred to the object
  the hands touch;
* perception sees every object where it is now, but earlier subtasks may move it: a subtask whose
  hands hold an object with a placement goal is keyframed at the goal (its contacts and floor feet
  moved rigidly with the object), and later contacts on a moved object move with it
  (:class:`_Displacement`).

Then :func:`build_problem` assembles scene, keyframes, schedule and options into the TO's problem.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from lomanip_to.problem import FLOOR, Options, PlacementGoal, Problem, SceneObject

from lomanip_to.route import footprint_of

from .grasp import antipodal_squeeze
from .retargeting import FEET, HANDS, LimbTarget, Obstacle, RetargetTarget, Retargeter, RetargetingError
from .schedule import Schedule, actions_of, Stance, SubtaskKeyframe, Timing, plan_schedule
from .symmetry import best_grasp_match, rotate_about, stance_cost, stance_yaw, yaw_symmetries


#: a keyframe whose hands take up (pick) or hold (place) a lifted object keeps the robot-and-object
#: CoM at least this far inside its feet's support polygon (the soles shrunk by the TO's CoP margin,
#: lomanip_to.model.SOLE_FORCE_POINTS), its floor feet stepping towards the load when it is not;
#: None switches the step off. Why: S2's pick kept the person's stance, feet 0.58 m behind the
#: hands, and the robot-and-box CoM 2 cm past the toes made the carry's first knot infeasible
#: (docs/planner_s1.md, sessions 33-34).
LOAD_BALANCE_MARGIN: float | None = 0.02
#: a pick's two-handed squeeze on opposite faces is moved along them to be antipodal through the
#: object's CoM (grasp.antipodal_squeeze); False (the default) keeps the transferred points, as the
#: paper does. Measured on (session 35), not kept: S2's generated pick and carry still fell under
#: physics (3.78 s; 4.06 s with the transferred points), its executed hands rode up to 10-12 cm above
#: the box's centre all the same, and over the grids 41 of 48 loaded keyframes balanced 2 cm inside
#: the soles (42 without), S1's step onto a turned box at -3.6 / -4.7 cm (-2.2 / -2.4)
ANTIPODAL_SQUEEZE = False
#: weight of the load-aware CoM task in those re-solves (the contacts weigh 100-1000)
LOAD_BALANCE_COST = 100.0
#: the re-solves also restart from the IK's seeds (True) or descend from the keyframe alone. On
#: S2's place the restarts find the fixture-like squat (pelvis 0.58 m, +3.0 cm); from the keyframe
#: alone it stays at 0.75 m with the hips back (+3.3 cm), and the pick is 0.9 s faster
#: (docs/planner_s1.md, session 34). The S2 solves were measured with restarts.
LOAD_BALANCE_RESTARTS = True
#: IK re-solves at most: the first on the same feet, each next one stepping by the remaining
#: shortfall (the body moves with the feet)
LOAD_STANCE_STEPS = 4
#: longest total step of the feet towards a load (m)
LOAD_STANCE_MAX_SHIFT = 0.25
#: feet that stand on an object's top step towards a load only as far as their soles stay this far
#: inside its edges (m)
TOP_EDGE_MARGIN = 0.01


@dataclass(frozen=True)
class LoadBalance:
    """The balance of a keyframe whose hands hold ``mass`` kg: signed margins (m, positive inside)
    of the robot-and-load CoM in the support polygon before and after the feet stepped by
    ``shift`` (m, world xy)."""

    mass: float
    margin_before: float
    margin_after: float
    shift: np.ndarray


@dataclass
class SubtaskPerception:
    """What perception extracted for one subtask (world frame)."""

    index: int
    prompt: str
    contacts: list[LimbTarget]
    base_orientation_wxyz: np.ndarray | None = None
    joint_prior: dict[str, float] = field(default_factory=dict)
    #: the person's pelvis height as a fraction of its leg (retargeting.pelvis_height_ratio)
    pelvis_height_ratio: float | None = None


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


def obstacles_of(obj: SceneObject) -> list[Obstacle]:
    """The object's primitives as IK obstacles, in the world at the object's pose."""
    from lomanip_sim import frames as fr

    x, y, z, w = obj.quat_xyzw
    R = fr.quat_to_matrix(np.array([w, x, y, z], float))
    out = []
    for p in obj.primitives:
        c, s = np.cos(p.yaw), np.sin(p.yaw)
        Rp = R @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        half = p.half_extents()
        size = half if p.kind == "box" else half[[0, 2]]   # cylinder: radius, half height
        out.append(Obstacle(obj.id, p.kind, size, np.asarray(obj.position, float) + R @ np.asarray(p.position, float),
                            fr.matrix_to_quat(Rp)))
    return out


def scene_obstacles(objects: list[SceneObject], moved: dict[str, "_Displacement"]) -> tuple[Obstacle, ...]:
    """Every object's primitives where the plan has the object at this keyframe (moved by earlier
    subtasks): the retargeting IK keeps the robot clear of them."""
    return tuple(o for obj in objects for o in obstacles_of(_as_placed(obj, moved.get(obj.id))))


def _displaced(d: "_Displacement | None", t: LimbTarget) -> LimbTarget:
    return d.moved(t) if d is not None else t


def _world_contacts(contacts: list[LimbTarget], by_id: dict[str, SceneObject], moved: dict[str, "_Displacement"],
                    carried: "_Displacement | None") -> dict[str, LimbTarget]:
    """Perceived contacts where the plan has their objects (floor feet move with a carried object)."""
    return {c.limb: _displaced(moved.get(c.object_id) if c.object_id in by_id else carried, c) for c in contacts}


def _yaw_of(q_wxyz) -> float | None:
    from lomanip_sim import frames as fr

    return None if q_wxyz is None else fr.quat_to_yaw(np.asarray(q_wxyz, float))


def _orient(st: SubtaskPerception, by_id: dict[str, SceneObject], moved: dict[str, "_Displacement"],
            placements: dict[str, PlacementGoal], grasps: dict[str, dict[str, LimbTarget]], placing: str | None,
            feet_now: dict, held_now: set[str]) -> tuple[list[LimbTarget], float | None, PlacementGoal | None]:
    """The subtask's perceived contacts and pelvis yaw turned by the symmetry of the object the
    demonstration was transferred through (its first contact's object) that suits the robot best
    (symmetry.py); for a placement, the hands keep the grasp they picked the object with and the
    goal's yaw is chosen among its symmetric equivalents. Returns (contacts in the perceived frame,
    pelvis yaw in the perceived frame, the placement goal to use)."""
    contacts = list(st.contacts)
    yaw0 = _yaw_of(st.base_orientation_wxyz)
    pivot = next((c.object_id for c in contacts if c.object_id in by_id), None)
    syms = yaw_symmetries(by_id[pivot]) if pivot is not None and by_id[pivot].movable else (0.0,)
    goal = placements.get(placing) if placing is not None else None
    if len(syms) == 1 and (placing is None or placing not in grasps):
        return contacts, yaw0, goal
    centre = np.asarray(by_id[pivot].position, float)

    def turned(a: float) -> list[LimbTarget]:
        return [rotate_about(c, centre, a) if c.object_id in (pivot, "", FLOOR) else c for c in contacts]

    def turned_yaw(a: float) -> float | None:
        return None if yaw0 is None else yaw0 + a

    left, right = feet_now["left_foot"][0], feet_now["right_foot"][0]
    mid, yaw_now = 0.5 * (left + right), stance_yaw(left, right)
    stand_on = {c.object_id for c in contacts if c.limb in FEET}
    if placing is not None and placing in grasps:
        # the grasp is rigid: the demonstration's stance on the side its hands match the held grasp
        cands = {a: {c.limb: c for c in turned(a)} for a in syms}
        a_demo = best_grasp_match(cands, grasps[placing])
        contacts = [grasps[placing][c.limb] if c.limb in HANDS and c.object_id == placing and c.limb in grasps[placing]
                    else c for c in turned(a_demo)]
        yaw_demo = turned_yaw(a_demo)
        best = None
        for a in syms:   # the placed box's yaw: equivalent placements, the robot's stance differs
            g = replace(goal, yaw=float(goal.yaw + a))
            d = _Displacement.of(by_id[placing], g)
            m = {**moved, placing: d}
            world = _world_contacts(contacts, by_id, m, d)
            obstacles = [footprint_of(o, d.target if o.id == placing else _as_placed(o, m.get(o.id)).position,
                                      (0.0, 0.0, _as_placed(o, m.get(o.id)).yaw())) for o in by_id.values()
                         if o.primitives and o.id not in stand_on]
            route_obs = [fp for fp in obstacles if fp.name not in held_now]
            cost = stance_cost(world, None if yaw_demo is None else yaw_demo + d.dyaw, mid, yaw_now, obstacles,
                               route_obs).total
            if best is None or cost < best[0] - 1e-9:
                best = (cost, g)
        return contacts, yaw_demo, best[1]
    best = None
    obstacles = [footprint_of(o, _as_placed(o, moved.get(o.id)).position, (0.0, 0.0, _as_placed(o, moved.get(o.id)).yaw()))
                 for o in by_id.values() if o.primitives and o.id not in stand_on]
    route_obs = [fp for fp in obstacles if fp.name not in held_now]
    carried = next((moved[h] for h in held_now if h in moved), None)
    for a in syms:
        cs = turned(a)
        world = _world_contacts(cs, by_id, moved, carried)
        y = turned_yaw(a)
        if y is not None and carried is not None:
            y += carried.dyaw
        cost = stance_cost(world, y, mid, yaw_now, obstacles, route_obs).total
        if best is None or cost < best[0] - 1e-9:
            best = (cost, cs, turned_yaw(a))
    return best[1], best[2], goal


def _solve_keyframe(retargeter: Retargeter, st: SubtaskPerception, targets: tuple, base_orientation,
                    q: np.ndarray | None, obstacles: tuple[Obstacle, ...] = ()):
    """The keyframe's IK, relaxed step by step until it is feasible: the person's feet and pelvis
    height; then floor feet that may slide (the demonstrator's stance is an adult's: the G1 steps
    to where it reaches); then without the pelvis height (differential IK is local: a height the
    hands cannot reach from may leave it short). Returns (result, whether the feet slid, the
    rung's pelvis height ratio)."""
    ladder = [(False, st.pelvis_height_ratio), (True, st.pelvis_height_ratio)]
    if st.pelvis_height_ratio is not None:
        ladder.append((True, None))
    error = None
    for slide, ratio in ladder:
        try:
            res = retargeter.solve(RetargetTarget(targets, base_orientation, st.joint_prior, floor_feet_slide=slide,
                                                  pelvis_height_ratio=ratio, obstacles=obstacles), q)
            return res, slide, ratio
        except RetargetingError as exc:
            error = exc
    raise RetargetingError(error.code, f"subtask {st.index} ({st.prompt!r}): {error}") from error


def _hand_targets(st: SubtaskPerception, given: dict[str, LimbTarget], by_id: dict[str, SceneObject]) -> list[LimbTarget]:
    """The IK's hand targets from the world contacts ``given``; a hand on an unknown object is an error."""
    targets = []
    for limb in HANDS:
        if limb in given:
            c = given[limb]
            if c.object_id not in by_id:
                raise RetargetingError(-2, f"subtask {st.index}: {limb} touches unknown object {c.object_id!r}")
            targets.append(LimbTarget(limb, np.asarray(c.position, float), np.asarray(c.normal, float), c.object_id))
    return targets


def _hand_load(actions: list[str], targets: list[LimbTarget], by_id: dict[str, SceneObject],
               rolling: frozenset) -> tuple[float, np.ndarray] | None:
    """(mass kg, hands' midpoint) of what a pick or place keyframe's hands hold up; None if nothing
    (a push's rolling object rests on its wheels)."""
    if not {"pick", "place"} & set(actions):
        return None
    hands = [t for t in targets if t.limb in HANDS]
    held = {t.object_id for t in hands if t.object_id in by_id and by_id[t.object_id].movable
            and t.object_id not in rolling}
    mass = float(sum(by_id[o].mass for o in held))
    return (mass, np.mean([t.position for t in hands], axis=0)) if mass > 0.0 else None


def _feet_top(targets: list[LimbTarget], by_id: dict[str, SceneObject], moved: dict[str, "_Displacement"]):
    """The footprint (route.Footprint, where the plan has the object) of the one object both feet
    stand on; None on the floor, on two surfaces or on an unknown object."""
    surfaces = {t.object_id or FLOOR for t in targets if t.limb in FEET}
    if len(surfaces) != 1 or surfaces == {FLOOR} or next(iter(surfaces)) not in by_id:
        return None
    oid = next(iter(surfaces))
    o = _as_placed(by_id[oid], moved.get(oid))
    return footprint_of(o, o.position, o.rpy())


def _step_room(retargeter: Retargeter, step: np.ndarray, top) -> float:
    """The largest fraction (0-1) of ``step`` both feet can take, from the retargeter's current
    configuration, with their soles ``TOP_EDGE_MARGIN`` inside ``top`` (a route.Footprint: the top
    they stand on; None for the floor, which does not limit them)."""
    if top is None:
        return 1.0
    from lomanip_to.model import SOLE_CORNERS

    c, s = np.cos(top.yaw), np.sin(top.yaw)
    R = np.array([[c, -s], [s, c]])
    half = np.asarray(top.half, float) - TOP_EDGE_MARGIN
    d = R.T @ np.asarray(step, float)[:2]
    room = 1.0
    corners = retargeter.sole_points(SOLE_CORNERS)[:, :2]
    for p in (corners - np.asarray(top.centre, float)) @ R:   # rows: R^T (corner - centre)
        if np.any(np.abs(p) > half + 1e-9):
            return 0.0   # already past the margin: no step
        for i in range(2):
            if abs(d[i]) > 1e-12:
                room = min(room, ((half[i] if d[i] > 0 else -half[i]) - p[i]) / d[i])
    return max(room, 0.0)


def _balance_under_load(retargeter: Retargeter, st: SubtaskPerception, targets: list[LimbTarget], res,
                        base_orientation, ratio: float | None, obstacles: tuple[Obstacle, ...],
                        load: tuple[float, np.ndarray], top=None) -> tuple[object, list[LimbTarget], LoadBalance]:
    """The keyframe, balanced with its load: when the robot-and-load CoM is less than
    ``LOAD_BALANCE_MARGIN`` inside the soles, the IK is solved again with the load in its CoM task
    (at ``LOAD_BALANCE_COST``), first on the same feet, then with the floor feet stepped towards
    the load by the remaining shortfall (at most ``LOAD_STANCE_STEPS`` solves and
    ``LOAD_STANCE_MAX_SHIFT``); a stepped solve the load-aware task keeps from its contacts is
    tried once more with the usual CoM task. A solve the IK cannot finish, or one that does not
    raise the margin, ends the search with the best keyframe so far. Feet on an object's top (``top``, a
    route.Footprint) step only as far as their soles stay on it (:func:`_step_room`)."""
    from lomanip_to.model import SOLE_FORCE_POINTS

    t0, spent = time.perf_counter(), res.seconds
    margin, normal = retargeter.support_margin(SOLE_FORCE_POINTS, *load)
    first, total = margin, np.zeros(2)
    feet_on = {t.object_id or FLOOR for t in targets if t.limb in FEET}
    can_step = sum(t.limb in FEET for t in targets) == 2 and (feet_on == {FLOOR} or top is not None)
    for k in range(LOAD_STANCE_STEPS if LOAD_BALANCE_MARGIN is not None else 0):
        deficit = LOAD_BALANCE_MARGIN - margin
        if deficit <= 1e-3 or (k > 0 and not can_step) or np.linalg.norm(total + deficit * normal) > LOAD_STANCE_MAX_SHIFT:
            break
        step = np.zeros(3)
        if k > 0:
            retargeter.configuration.update(res.qpos)
            step = np.array([*(deficit * normal), 0.0])
            step *= _step_room(retargeter, step, top)
            if np.linalg.norm(step) < 1e-3:
                break
        moved = [replace(t, position=t.position + step) if t.limb in FEET else t for t in targets]
        new = None
        # the load-aware CoM task first; on stepped feet, if its weight keeps a hand from its
        # contact, the usual CoM task (S1's one-handed reach from the box top to the shelf)
        for mass, cost in ((load[0], LOAD_BALANCE_COST),) + (((0.0, 1.0),) if k > 0 else ()):
            try:
                new = retargeter.solve(RetargetTarget(tuple(moved), base_orientation, st.joint_prior,
                                                      floor_feet_slide=False, pelvis_height_ratio=ratio,
                                                      obstacles=obstacles, load_mass=mass, load_point=load[1],
                                                      balance_cost=cost), res.qpos, restarts=LOAD_BALANCE_RESTARTS)
                break
            except RetargetingError:
                continue
        if new is None:
            if k == 0 and can_step:
                continue   # the same feet cannot balance it: step
            break
        new_margin, new_normal = retargeter.support_margin(SOLE_FORCE_POINTS, *load)
        if new_margin <= margin:
            if k == 0 and can_step:
                continue
            break
        res, targets, margin, normal, total = new, moved, new_margin, new_normal, total + step[:2]
    retargeter.configuration.update(res.qpos)
    # the keyframe's IK time counts every solve it took
    res = replace(res, seconds=spent + time.perf_counter() - t0)
    return res, targets, LoadBalance(load[0], first, margin, total)


def retarget_subtasks(subtasks: list[SubtaskPerception], objects: list[SceneObject], stance: Stance,
                      retargeter: Retargeter, placements: dict[str, PlacementGoal] | None = None,
                      current_qpos: np.ndarray | None = None,
                      push_distance: float = PUSH_DISTANCE) -> list[SubtaskKeyframe]:
    """One retargeted keyframe per subtask, chained (each starts from the previous solution)."""
    from lomanip_sim import frames as fr

    by_id = {o.id: o for o in objects}
    placements = dict(placements or {})
    feet_now = {"left_foot": (stance.left.copy(), stance.left_surface),
                "right_foot": (stance.right.copy(), stance.right_surface)}
    out: list[SubtaskKeyframe] = []
    # The first IK starts from the retargeter's own seeds, not from the measured state: a seed that
    # differs by sensor-level noise can flip which local solution the IK finds (feet kept vs slid),
    # and with it the footsteps of the whole plan. ``current_qpos`` is kept for callers' records.
    q = None
    moved: dict[str, _Displacement] = {}
    grasps: dict[str, dict[str, LimbTarget]] = {}   # object -> hand contacts it is held by (perceived frame)
    held_now: set[str] = set()
    rolling = frozenset(o.id for o in objects if o.object_class == "trolley")
    for st in subtasks:
        targets: list[LimbTarget] = []
        actions = actions_of(st.prompt)
        held = [c.object_id for c in st.contacts if c.limb in HANDS]
        placing = next((oid for oid in held if oid in placements and oid in by_id), None) \
            if "place" in actions else None
        contacts, base_yaw, goal = _orient(st, by_id, moved, placements, grasps, placing, feet_now, held_now)
        squeezed = antipodal_squeeze(contacts, by_id, rolling) if "pick" in actions and ANTIPODAL_SQUEEZE else None
        if placing is not None:
            placements[placing] = goal
            moved[placing] = _Displacement.of(by_id[placing], goal)
        carried = next((moved[oid] for oid in held if oid in moved), None)
        given = _world_contacts(contacts, by_id, moved, carried)
        if base_yaw is not None and carried is not None:
            base_yaw += carried.dyaw
        base_orientation = None if base_yaw is None else fr.yaw_to_quat(base_yaw)
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
        obstacles = scene_obstacles(objects, moved)
        # the antipodal squeeze first; the transferred hand points if the IK cannot reach it
        t0 = time.perf_counter()
        for cs in [cs for cs in (squeezed, contacts) if cs is not None]:
            hands = _hand_targets(st, _world_contacts(cs, by_id, moved, carried), by_id)
            try:
                res, slid, ratio = _solve_keyframe(retargeter, st, tuple(targets + hands), base_orientation, q,
                                                   obstacles)
            except RetargetingError:
                if cs is contacts:
                    raise
                continue
            contacts, targets = cs, targets + hands
            break
        res = replace(res, seconds=time.perf_counter() - t0)   # every rung and grasp the IK tried
        if slid:
            targets = [LimbTarget(t.limb, res.contact_points[t.limb].copy(), t.normal, t.object_id)
                       if t.limb in FEET else t for t in targets]
        load = _hand_load(actions, targets, by_id, rolling)
        balance = None
        if load is not None:
            res, targets, balance = _balance_under_load(retargeter, st, targets, res, base_orientation, ratio,
                                                        obstacles, load, _feet_top(targets, by_id, moved))
        for t in targets:
            if t.limb in FEET:
                feet_now[t.limb] = (t.position.copy(), t.object_id)
        q = res.qpos
        hand_objects = [t.object_id for t in targets if t.limb in HANDS]
        if placing is not None:
            held_now.discard(placing)
        if "pick" in actions:
            for oid in dict.fromkeys(hand_objects):
                grasps[oid] = {c.limb: c for c in contacts if c.limb in HANDS and c.object_id == oid}
                held_now.add(oid)
        placement = next((placements[oid] for oid in hand_objects if oid in placements), None)
        push_feet = []
        if "push" in actions and hand_objects:
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
                                   retarget=res, push_feet=push_feet, load_balance=balance))
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
