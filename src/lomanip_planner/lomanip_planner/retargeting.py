"""Retargeting (paper Sec. III-A3): contacts + a human pose -> a feasible 35-D G1 keyframe.

IK on the same G1 model the simulator uses (g1.xml + hand sites): mink's tasks and limits, with
its QP step used inside a Levenberg-Marquardt descent (``lomanip_planner.ik``) so the keyframe is a
(local) minimum of one weighted task cost and moves continuously with its targets:

* hand and foot contacts are the primary tasks (high weight); a keyframe is accepted only if every
  contact is reached within ``contact_tolerance`` (1 cm by default);
* stance feet are flat on their surface (sole normal = surface normal, yaw from the base);
* the base orientation comes from the human body (rigid transform of the demonstration);
* the human joint angles mapped onto the G1's matching joints act as a posture regulariser
  (HumanPlus-style: only joints with a counterpart are used);
* the CoM is pulled over the mid-foot point so stance keyframes are statically plausible;
* the pelvis is pulled up to the human's pelvis height (relative to leg length), never down;
* several starts (the current pose, standing, squatting, arms up, in front of the hands' targets)
  descend; the collision-free one that reaches its contacts with the lowest cost wins;
* joint limits and self-collision (arms vs torso, leg vs leg, hands vs thighs) are hard limits;
* so is clearance from the scene's objects (:class:`Obstacle`: the primitives of every object where
  the plan has it at this keyframe): every robot collision geom keeps ``OBJECT_CLEARANCE`` from
  them, except a contacting hand's wrist and hand against the object it touches and a foot against
  the object it stands on.

Simplification (named): hand orientation is not constrained (point contacts, as in the TO).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import lomanip_sim  # noqa: F401  (headless GL default before mujoco loads)
import mink
import mujoco
import numpy as np

from lomanip_sim import frames, world
from lomanip_sim.robot_model import G1_JOINT_NAMES, g1_mjcf_path

from .balance import combined_com, convex_hull, support_margin
from .ik import ComOverFeetTask, DescentResult, PelvisFloorTask, minimise

#: lomanip_msgs/ErrorCode values used here.
RETARGETING_INFEASIBLE = -5
INVALID_REQUEST = -1

LIMBS = ("left_foot", "right_foot", "left_hand", "right_hand")
FEET = ("left_foot", "right_foot")
HANDS = ("left_hand", "right_hand")

#: Self-collision pairs checked as hard limits (bodies whose collision geoms must stay apart).
_SELF_COLLISION_BODIES = (
    (("left_elbow_link", "left_wrist_roll_link", "left_wrist_pitch_link", "left_wrist_yaw_link"),
     ("torso_link", "pelvis", "left_hip_pitch_link", "left_hip_roll_link", "left_knee_link")),
    (("right_elbow_link", "right_wrist_roll_link", "right_wrist_pitch_link", "right_wrist_yaw_link"),
     ("torso_link", "pelvis", "right_hip_pitch_link", "right_hip_roll_link", "right_knee_link")),
    (("left_knee_link", "left_ankle_pitch_link", "left_ankle_roll_link"),
     ("right_knee_link", "right_ankle_pitch_link", "right_ankle_roll_link")),
    (("left_wrist_yaw_link",), ("right_wrist_yaw_link",)),
)

#: clearance the IK keeps between the robot's collision geoms and the scene's objects (m). Without
#: it S1's pick keyframe had both knees and thighs 9-10 cm inside the box being picked up, and the
#: TO had to push the legs out (issue 5)
OBJECT_CLEARANCE = 0.015
#: a keyframe deeper than this inside an object is infeasible (m)
OBJECT_PENETRATION_TOLERANCE = 0.002
#: weight of the soft clearance (:class:`ObjectClearanceTask`), as the feet's
OBJECT_CLEARANCE_COST = 1000.0
#: the hard limit keeps this much more than the soft clearance (m). With both at one distance a
#: step the limit allowed often crossed the clearance by its linearisation error, the cost rose,
#: the descent refused it and crawled: S1's pick took 600 instead of 450 steps and S2's push
#: keyframe 700 instead of 541, ending elsewhere
OBJECT_LIMIT_MARGIN = 0.002
#: pairs nearer than this (m) are limited in a step (mink's collision_detection_distance; the
#: self-collision limit's 0.15 m made several times more distance queries). A pair farther away
#: that one step would take inside an object raises the clearance cost, so the step is refused
OBJECT_DETECTION_DISTANCE = 0.05
#: obstacle geoms the IK model holds; a scene with more primitives keeps those nearest the contacts
MAX_OBSTACLES = 32
#: bodies of a limb that touch the object its contact is on, so are not kept clear of that object:
#: a hand's contact site is the centre of its collision box, and the sole spheres rest on the surface
_CONTACT_BODIES = {
    "left_hand": ("left_wrist_roll_link", "left_wrist_pitch_link", "left_wrist_yaw_link"),
    "right_hand": ("right_wrist_roll_link", "right_wrist_pitch_link", "right_wrist_yaw_link"),
    "left_foot": ("left_ankle_pitch_link", "left_ankle_roll_link"),
    "right_foot": ("right_ankle_pitch_link", "right_ankle_roll_link"),
}
#: a start inside an object is moved away from it in steps of this (m), at most SEED_BACKOFF_MAX
SEED_BACKOFF = 0.05
SEED_BACKOFF_MAX = 0.6
#: where unused obstacle geoms wait (far below the floor, outside every pair anyway)
_PARKED = (0.0, 0.0, -100.0)

#: a descent stops when this many steps lower its cost by less than IK_STALL_TOLERANCE of it
#: (``ik.minimise``); 0 descends to the iteration cap. The tail it cuts moved the cost by under 1 %
IK_STALL_WINDOW = 10
IK_STALL_TOLERANCE = 1e-3

#: weight of the pelvis height prior (hands 100-1000, feet 1000, base orientation 5, posture 0.01).
#: At 3 (until session 52) it lost to the hands: S1's generated pick and place squatted at 0.21 /
#: 0.20 m (the person at 49 % of its leg, the fixture's pick 0.31 m); at 30 they keep 0.36 / 0.39 m
#: and S1 from prompts converges (docs/planner_s1.md, session 52)
PELVIS_HEIGHT_COST = 30.0
#: more than this fraction of the leg above the person's pelvis height the pelvis is pulled down
#: (weight PELVIS_CEILING_COST); None (the default): no ceiling. Measured, not yet on: S2's place,
#: demonstrated in a squat (74 % of the leg), stands the G1 at 0.77 m bent over the deck with its
#: pelvis 17 cm ahead of its feet, and the TO does not converge from it (sessions 29, 32). With a
#: ceiling at 0.15 the IK finds a 0.39 m squat instead (another start wins once standing costs);
#: the fixture the TO converges from squats to 0.58 m (docs/planner_s1.md, session 33)
PELVIS_HEIGHT_BAND: float | None = None
PELVIS_CEILING_COST = 30.0


def pelvis_height_ratio(keypoints: Mapping[str, np.ndarray]) -> float | None:
    """A person's pelvis height above its feet over its straight-leg pelvis height (hip-knee +
    knee-ankle + ankle above the sole), from world keypoints; None when some are missing."""
    try:
        legs = []
        for side in ("left", "right"):
            hip, knee, ankle, foot = (np.asarray(keypoints[f"{side}_{k}"], float) for k in ("hip", "knee", "ankle", "foot"))
            legs.append(np.linalg.norm(hip - knee) + np.linalg.norm(knee - ankle) + abs(ankle[2] - foot[2]))
        feet_z = 0.5 * (float(keypoints["left_foot"][2]) + float(keypoints["right_foot"][2]))
        height = float(keypoints["pelvis"][2]) - feet_z
    except KeyError:
        return None
    leg = float(np.mean(legs))
    if leg < 1e-3 or not np.isfinite(height):
        return None
    return float(np.clip(height / leg, 0.3, 1.0))


#: horizontal distance from the pelvis to where both hands hold an object in front of the G1 (m)
HAND_REACH = 0.32

#: leg joints (rad) of the squatting and crouched IK starts
_SQUAT_LEGS = (("hip_pitch", -0.9), ("knee", 1.8), ("ankle_pitch", -0.8))
#: crouched starts for hands low in front (pelvis height m, waist pitch, shoulder pitch, shoulder
#: roll outward, rad). Differential IK from a standing start must fold the legs, bend the waist and
#: bring the arms outside the knees at once, and with the self-collision limits it often stops in a
#: local minimum (S1's "pick up the box": hands at 15 cm, 40 cm apart). Seeds measured on that case.
_CROUCH_SEEDS = {
    "crouch": (0.35, 0.6, -0.8, 0.0),
    "crouch_wide": (0.5, 0.3, -0.8, 0.35),
}
#: (seed, pelvis-to-hands distance m) tried, in order, in front of the hands when feet may slide
_FRONT_SEEDS = (("crouch", 0.35), ("crouch", 0.25), ("crouch_wide", 0.35), ("squat", HAND_REACH),
                ("stand", HAND_REACH))


class RetargetingError(ValueError):
    """The targets cannot be met by a feasible G1 configuration; ``code`` is an ErrorCode value."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class LimbTarget:
    """Where a limb must touch: a world point on ``object_id`` with the outward surface normal."""

    limb: str
    position: np.ndarray
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    object_id: str = "floor"


def _sphere_to_box_gaps(model: mujoco.MjModel, data: mujoco.MjData, robot: np.ndarray,
                        obstacle: np.ndarray) -> np.ndarray:
    """Lower bounds of the pairs' distances (m): each robot geom's bounding sphere to its obstacle
    geom's box (``geom_aabb``, set to the obstacle's extents). Much tighter than two spheres (mink's
    broadphase) for a shelf's long legs, so few pairs reach the exact (costly) distance query."""
    R = data.geom_xmat[obstacle].reshape(-1, 3, 3)
    local = np.einsum("nji,nj->ni", R, data.geom_xpos[robot] - data.geom_xpos[obstacle])
    outside = np.maximum(np.abs(local) - model.geom_aabb[obstacle, 3:], 0.0)
    return np.sqrt(np.einsum("ni,ni->n", outside, outside)) - model.geom_rbound[robot]


class ObjectProximity:
    """The robot-obstacle pairs nearer than ``reach`` at one configuration: their signed distances
    (MuJoCo's ``mj_geomDistance``) and the distances' Jacobians. Computed once per q and shared by
    :class:`ObjectClearanceLimit` and :class:`ObjectClearanceTask`, which the descent asks at every
    step: one distance query per pair and step instead of one per user."""

    def __init__(self, pairs: Sequence[tuple[int, int]], reach: float) -> None:
        self.pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)   # (robot geom, obstacle geom)
        self.reach = float(reach)
        #: the last two configurations: the descent asks at a trial step and, when it refuses it,
        #: again at the point it came from
        self._cache: list[tuple[bytes, np.ndarray, np.ndarray, np.ndarray]] = []

    def near(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pair indices, signed distances m, d distance / dq rows) of the pairs within ``reach``."""
        key = configuration.q.tobytes()
        for cached in self._cache:
            if cached[0] == key:
                return cached[1], cached[2], cached[3]
        model, data = configuration.model, configuration.data
        robot, obstacle = self.pairs[:, 0], self.pairs[:, 1]
        fromto, jac_point = np.zeros(6), np.zeros((3, model.nv))
        index, distance, rows = [], [], []
        for i in np.flatnonzero(_sphere_to_box_gaps(model, data, robot, obstacle) < self.reach):
            d = mujoco.mj_geomDistance(model, data, robot[i], obstacle[i], self.reach, fromto)
            normal = fromto[3:] - fromto[:3]   # robot witness point -> obstacle's (reversed inside)
            length = float(np.linalg.norm(normal))
            if d >= self.reach or length < 1e-12:
                continue
            # the obstacle is fixed: d moves with the robot's witness point along the normal
            mujoco.mj_jac(model, data, jac_point, None, fromto[:3], model.geom_bodyid[robot[i]])
            index.append(i)
            distance.append(d)
            rows.append((-1.0 if d >= 0.0 else 1.0) * (normal / length) @ jac_point)
        entry = (key, np.asarray(index, dtype=int), np.asarray(distance, float), np.reshape(rows, (-1, model.nv)))
        self._cache = [entry, *self._cache[:1]]
        return entry[1], entry[2], entry[3]


class ObjectClearanceLimit(mink.Limit):
    """mink's collision-avoidance rows (``CollisionAvoidanceLimit``: same bound and gain) on the
    near pairs of an :class:`ObjectProximity`: in a step's linearisation no pair comes closer than
    ``minimum``, and one farther approaches by at most gain * (d - minimum)."""

    def __init__(self, proximity: ObjectProximity, minimum: float, gain: float = 0.85) -> None:
        self.proximity = proximity
        self.minimum = float(minimum)
        self.gain = float(gain)

    def compute_qp_inequalities(self, configuration: mink.Configuration, dt: float) -> mink.Constraint:
        _, distance, jac = self.proximity.near(configuration)
        if not len(distance):
            return mink.Constraint()
        bound = np.where(distance > self.minimum, self.gain * (distance - self.minimum) / dt, 0.0)
        return mink.Constraint(G=-jac, h=bound)


class ObjectClearanceTask(mink.Task):
    """Soft side of the object clearance: the ``rows`` nearest pairs inside ``clearance``, each with
    error min(0, d - clearance).

    The limit only stops a pair from getting closer in the linearised step, and nothing pushes back
    a pair that the curvature of a limb's motion took below it: over hundreds of steps S1's place
    keyframe crept from 15 to 11 mm (an elbow by the box) and its basket grab to -0.5 mm. As a cost
    that is zero outside the clearance (the limit keeps ``OBJECT_LIMIT_MARGIN`` more) this pushes
    such pairs back out without moving a keyframe that keeps clear; squared, it is continuously
    differentiable while at most ``rows`` pairs are inside (the limit keeps that few). A few rows,
    not one per pair (hundreds), keep the QP small.
    """

    def __init__(self, proximity: ObjectProximity, clearance: float, cost: float, rows: int = 12) -> None:
        super().__init__(cost=np.full(rows, cost), gain=1.0, lm_damping=0.0)
        self.proximity = proximity
        self.clearance = float(clearance)
        self.rows = rows

    def _inside(self, configuration: mink.Configuration) -> tuple[np.ndarray, np.ndarray]:
        _, distance, jac = self.proximity.near(configuration)
        order = [k for k in np.argsort(distance, kind="stable") if distance[k] < self.clearance][:self.rows]
        return distance[order], jac[order]

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        distance, _ = self._inside(configuration)
        error = np.zeros(self.rows)
        error[:len(distance)] = distance - self.clearance
        return error

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        _, jac = self._inside(configuration)
        out = np.zeros((self.rows, configuration.model.nv))
        out[:len(jac)] = jac
        return out


@dataclass(frozen=True)
class Obstacle:
    """One primitive of a scene object, where the plan has the object at this keyframe (world).

    ``kind`` is "box" (``size``: half extents) or "cylinder" (``size``: radius, half height; axis
    along the primitive's z), as MuJoCo sizes its geoms.
    """

    object_id: str
    kind: str
    size: np.ndarray
    position: np.ndarray
    quat_wxyz: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))


@dataclass(frozen=True)
class RetargetTarget:
    """What one keyframe must satisfy (world frame)."""

    limb_targets: tuple[LimbTarget, ...]
    #: pelvis orientation (w, x, y, z) from the human body; None = keep the current yaw, level
    base_orientation_wxyz: np.ndarray | None = None
    #: human joint angles mapped onto G1 joint names (regulariser toward a human-like posture)
    joint_prior: Mapping[str, float] = field(default_factory=dict)
    #: feet pitch relative to their surface (the paper constrains it; 0 = flat)
    feet_pitch: float = 0.0
    #: feet on the floor keep their height and flat orientation but may slide horizontally (weak
    #: pull to their target): the demonstrator's stance suits an adult, not the smaller G1, so
    #: when the hands cannot reach from the human's foot positions the robot steps closer, as the
    #: paper's foot-position cost (eq. 2) later asks of the TO. The residual of such a foot is its
    #: height error; its final position becomes the keyframe's foot target.
    floor_feet_slide: bool = False
    #: the human's pelvis height above its feet as a fraction of its straight-leg pelvis height
    #: (:func:`pelvis_height_ratio`); while the G1's pelvis is below the same fraction of its own
    #: leg it is pulled up (a soft one-sided bound: never pulled down). None = no bound. Why: the
    #: human joint angles alone let the shorter-armed G1 sink into a squat far deeper than the
    #: person's (S1's pick: pelvis 0.16-0.19 m while the person's was at 49 % of its leg)
    pelvis_height_ratio: float | None = None
    #: the scene's solids the robot must stay clear of (contacting limbs excepted, see
    #: ``_CONTACT_BODIES``); empty = no scene
    obstacles: tuple[Obstacle, ...] = ()
    #: a point load (kg, world m; the object the hands hold up) the CoM task balances with the
    #: robot, at ``balance_cost`` (the default 1 lets the contacts, 100-1000, win)
    load_mass: float = 0.0
    load_point: np.ndarray | None = None
    balance_cost: float = 1.0


@dataclass
class RetargetResult:
    qpos: np.ndarray                 # 36: base position, base quaternion (w, x, y, z), 29 joints
    residuals: dict[str, float]      # limb -> distance between its contact point and the target (m)
    foot_tilt: dict[str, float]      # stance foot -> angle between sole normal and surface normal (rad)
    min_self_distance: float         # m, over the self-collision pairs (negative = penetration)
    within_joint_limits: bool
    iterations: int
    seconds: float
    #: limb -> where its contact point ended (feet: sole centre on the surface), world frame
    contact_points: dict[str, np.ndarray] = field(default_factory=dict)
    #: m, robot geoms vs the target's obstacles, contact pairs excepted (negative = penetration;
    #: inf without obstacles), and which robot body and object it is
    min_object_distance: float = float("inf")
    closest_object_pair: str = ""

    @property
    def base_position(self) -> np.ndarray:
        return self.qpos[:3]

    @property
    def base_quat_wxyz(self) -> np.ndarray:
        return self.qpos[3:7]

    @property
    def joints(self) -> dict[str, float]:
        return dict(zip(G1_JOINT_NAMES, self.qpos[7:].tolist()))


def _ik_model(slots: int) -> mujoco.MjModel:
    """The simulator's G1 (built as ``world.build_robot_model`` builds it, with the same two steps)
    plus ``slots`` mocap bodies of one geom each, which each solve shapes and poses as its
    obstacles: a compiled model cannot gain geoms, and MuJoCo's distance queries need robot and
    obstacles in one model. The obstacle bodies come after the robot's, so every robot body and
    geom id is the same as in the robot's model (tests/planner/test_retargeting_objects.py)."""
    try:
        spec = mujoco.MjSpec.from_file(str(g1_mjcf_path()))
    except Exception as e:  # mujoco raises plain ValueError on parse problems
        raise world.WorldBuildError(f"cannot load {g1_mjcf_path()}: {e}") from e
    world._convert_actuators_to_motors(spec)
    world._add_hands(spec)
    for k in range(slots):
        body = spec.worldbody.add_body()
        body.name, body.mocap, body.pos = f"ik_obstacle_{k}", True, list(_PARKED)
        geom = body.add_geom()
        geom.name, geom.type, geom.size = f"ik_obstacle_{k}", mujoco.mjtGeom.mjGEOM_BOX, [0.01, 0.01, 0.01]
        geom.contype, geom.conaffinity, geom.group = 0, 1, 4   # touches the robot, not each other
    return spec.compile()


def _bounding_radius(o: Obstacle) -> float:
    r, h = float(o.size[0]), float(o.size[1])
    return float(np.linalg.norm(o.size)) if o.kind == "box" else float(np.hypot(r, h))


def _finite(v, n: int, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.size != n or not np.all(np.isfinite(a)):
        raise RetargetingError(INVALID_REQUEST, f"{what} must be {n} finite numbers, got {a.tolist()}")
    return a


class Retargeter:
    """Solves keyframes by IK (a descent on mink's QP); build once, call :meth:`solve` per keyframe."""

    def __init__(self, max_iterations: int = 400, screen_iterations: int = 100, contact_tolerance: float = 0.01,
                 solver: str = "daqp") -> None:
        self.model = _ik_model(MAX_OBSTACLES)
        self._obstacle_geoms = [self.model.geom(f"ik_obstacle_{k}").id for k in range(MAX_OBSTACLES)]
        self._obstacle_bodies = [self.model.body(f"ik_obstacle_{k}").mocapid[0] for k in range(MAX_OBSTACLES)]
        self.max_iterations = max_iterations
        self.screen_iterations = min(screen_iterations, max_iterations)
        self.contact_tolerance = contact_tolerance
        self.solver = solver
        self.configuration = mink.Configuration(self.model)
        self.stand = self.model.key("stand").qpos.copy()
        self._sliding: set[str] = set()   # feet allowed to slide in the current solve
        self.sole_offset = self._measure_sole_offset()
        self.leg_length = self._measure_leg_length()
        self.limb_tasks = {
            # Feet carry the robot: they outrank the hands, so an unreachable hand target shows as
            # a hand residual instead of a lifted foot.
            limb: mink.FrameTask(limb, "site", position_cost=1000.0 if limb in FEET else 100.0,
                                 orientation_cost=200.0 if limb in FEET else 0.0, lm_damping=1e-2)
            for limb in LIMBS
        }
        self.base_task = mink.FrameTask("pelvis", "body", position_cost=0.0, orientation_cost=5.0)
        self.com_task = ComOverFeetTask(FEET, cost=1.0)
        self.posture_task = mink.PostureTask(self.model, cost=1e-2)
        self._pairs = self._collision_pairs()
        self._robot_geoms = self._robot_collision_geoms()
        self.limits = [mink.ConfigurationLimit(self.model),
                       mink.CollisionAvoidanceLimit(self.model, self._pairs,
                                                    minimum_distance_from_collisions=0.01,
                                                    collision_detection_distance=0.15)]
        #: (robot geom, obstacle geom, object id) kept apart in the current solve
        self._object_pairs: list[tuple[int, int, str]] = []
        self._limits: list[mink.Limit] = list(self.limits)   # the current solve's limits
        self._clearance_task: ObjectClearanceTask | None = None

    def _measure_sole_offset(self) -> float:
        """Height of the foot site above the sole (the lowest point of the foot contact spheres)."""
        data = mujoco.MjData(self.model)
        data.qpos[:] = self.stand
        mujoco.mj_kinematics(self.model, data)
        foot_body = self.model.site("left_foot").bodyid
        bottoms = [data.geom_xpos[g][2] - self.model.geom_size[g][0] for g in range(self.model.ngeom)
                   if self.model.geom_bodyid[g] == foot_body and self.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE]
        return float(data.site("left_foot").xpos[2] - min(bottoms))

    def _measure_leg_length(self) -> float:
        """Pelvis height above the soles with straight legs (every joint at zero)."""
        data = mujoco.MjData(self.model)
        data.qpos[:] = 0.0
        data.qpos[3] = 1.0
        mujoco.mj_kinematics(self.model, data)
        sole = min(data.site(f).xpos[2] for f in FEET) - self.sole_offset
        return float(data.xpos[self.model.body("pelvis").id][2] - sole)

    def _collision_pairs(self) -> list[tuple[list[int], list[int]]]:
        def geoms(bodies: Sequence[str]) -> list[int]:
            ids = [self.model.body(b).id for b in bodies]
            return [g for g in range(self.model.ngeom)
                    if self.model.geom_bodyid[g] in ids and self.model.geom_contype[g]]
        return [(geoms(a), geoms(b)) for a, b in _SELF_COLLISION_BODIES]

    def _robot_collision_geoms(self) -> list[int]:
        """Every colliding geom of the robot (the pelvis subtree), the side kept clear of objects."""
        pelvis = self.model.body("pelvis").id
        return [g for g in range(self.model.ngeom) if self.model.geom_contype[g]
                and self.model.body_rootid[self.model.geom_bodyid[g]] == pelvis]

    def _place_obstacles(self, obstacles: Sequence[Obstacle], targets: dict[str, LimbTarget]) -> list[tuple[int, str]]:
        """Shapes and poses the model's obstacle geoms as ``obstacles`` (the ``MAX_OBSTACLES``
        nearest the contacts when there are more) and parks the rest; returns (geom, object id)
        of those in use."""
        model, data = self.model, self.configuration.data
        centre = np.mean([t.position for t in targets.values()], axis=0)
        order = sorted(obstacles, key=lambda o: float(np.linalg.norm(np.asarray(o.position) - centre))
                       - _bounding_radius(o))
        placed = []
        for k, (g, mocap) in enumerate(zip(self._obstacle_geoms, self._obstacle_bodies)):
            if k >= len(order):
                data.mocap_pos[mocap], data.mocap_quat[mocap] = _PARKED, (1.0, 0.0, 0.0, 0.0)
                continue
            o = order[k]
            if o.kind not in ("box", "cylinder"):
                raise RetargetingError(INVALID_REQUEST, f"obstacle of {o.object_id!r} has unknown kind {o.kind!r}")
            size = _finite(o.size, 3 if o.kind == "box" else 2, f"{o.object_id} obstacle size")
            quat = _finite(o.quat_wxyz, 4, f"{o.object_id} obstacle orientation")
            if np.any(size <= 0.0) or np.linalg.norm(quat) < 1e-9:
                raise RetargetingError(INVALID_REQUEST,
                                       f"obstacle of {o.object_id!r} has an empty size or a zero quaternion")
            # MuJoCo's distance functions read the size, the broadphase here the box (geom_aabb)
            # and MuJoCo's own the bounding radius: all three follow the shape.
            model.geom_type[g] = mujoco.mjtGeom.mjGEOM_BOX if o.kind == "box" else mujoco.mjtGeom.mjGEOM_CYLINDER
            model.geom_size[g] = np.append(size, 0.0) if o.kind == "cylinder" else size
            model.geom_rbound[g] = _bounding_radius(o)
            model.geom_aabb[g] = np.concatenate([np.zeros(3), size if o.kind == "box" else size[[0, 0, 1]]])
            data.mocap_pos[mocap] = _finite(o.position, 3, f"{o.object_id} obstacle position")
            data.mocap_quat[mocap] = quat / np.linalg.norm(quat)
            placed.append((g, o.object_id))
        return placed

    def _set_obstacles(self, obstacles: Sequence[Obstacle], targets: dict[str, LimbTarget]) -> None:
        """This solve's robot-object pairs and limits: every robot collision geom against every
        obstacle, except the bodies of a limb (``_CONTACT_BODIES``) against the object it touches."""
        placed = self._place_obstacles(obstacles, targets)
        touching: dict[str, set[int]] = {}
        for limb, t in targets.items():
            bodies = {self.model.body(b).id for b in _CONTACT_BODIES[limb]}
            touching.setdefault(t.object_id, set()).update(
                g for g in self._robot_geoms if self.model.geom_bodyid[g] in bodies)
        self._object_pairs = [(r, g, oid) for g, oid in placed for r in self._robot_geoms
                              if r not in touching.get(oid, ())]
        self._limits = list(self.limits)
        self._clearance_task = None
        if self._object_pairs:
            proximity = ObjectProximity([(r, g) for r, g, _ in self._object_pairs], OBJECT_DETECTION_DISTANCE)
            self._limits.append(ObjectClearanceLimit(proximity, OBJECT_CLEARANCE + OBJECT_LIMIT_MARGIN))
            self._clearance_task = ObjectClearanceTask(proximity, OBJECT_CLEARANCE, OBJECT_CLEARANCE_COST)

    # ------------------------------------------------------------------------------------------
    def solve(self, target: RetargetTarget, initial_qpos: np.ndarray | None = None,
              restarts: bool = True) -> RetargetResult:
        """A keyframe meeting ``target``; raises :class:`RetargetingError` if none is found.

        Differential IK is local: when the first start (``initial_qpos``, else standing over the
        feet) misses a contact, it restarts from a squat and from an arms-up posture and keeps the
        best solution. ``restarts`` False descends from ``initial_qpos`` alone (a keyframe refined
        from a solution it is near).
        """
        t0 = time.perf_counter()
        targets = self._check(target)
        self._sliding = {limb for limb, t in targets.items() if limb in FEET and target.floor_feet_slide
                         and t.object_id in ("", "floor")}
        feet = [t for t in targets.values() if t.limb in FEET]
        self._set_obstacles(target.obstacles, targets)
        base_R = self._base_rotation(target, feet)
        starts = [] if initial_qpos is None else [_finite(initial_qpos, 36, "initial_qpos")]
        seeded = restarts or initial_qpos is None
        if seeded:
            starts += [self._seed(name, feet, base_R) for name in ("stand", "squat", "reach_up")]
        hands = [t.position for t in targets.values() if t.limb in HANDS]
        if seeded and self._sliding and hands:   # feet may move: also start in front of the hands' targets
            hands_mid = np.mean(hands, axis=0)
            for name, reach in _FRONT_SEEDS:
                q = self._seed(name, feet, base_R)
                q[0:2] = (hands_mid - reach * base_R[:, 0])[:2]
                starts.append(q)
        starts = [self._clear_seed(q0) for q0 in starts]
        # Every start descends towards a local minimum of the same weighted task cost; the keyframe
        # is the collision-free one that reaches its contacts with the lowest cost (the first start
        # alone often ends bent over a box the human squatted to). Starts are compared after
        # ``screen_iterations``; the best one then descends on to ``max_iterations``.
        def score(outcome: DescentResult) -> tuple[bool, bool, float]:
            worst = max(self._residuals(targets).values())
            collides = self._min_self_distance() < 0.0 or \
                self._min_object_distance()[0] < -OBJECT_PENETRATION_TOLERANCE
            return collides, worst > self.contact_tolerance, outcome.cost

        best: tuple[tuple[bool, bool, float], np.ndarray, DescentResult] | None = None
        iterations_total = 0
        for q0 in starts:
            q, outcome = self._descend(target, targets, base_R, feet, q0, self.screen_iterations)
            iterations_total += outcome.iterations
            candidate = (score(outcome), q, outcome)
            if best is None or candidate[0] < best[0]:
                best = candidate
        if not best[2].converged and self.max_iterations > self.screen_iterations:
            q, outcome = self._descend(target, targets, base_R, feet, best[1],
                                       self.max_iterations - self.screen_iterations)
            iterations_total += outcome.iterations
            refined = score(outcome)
            if refined <= best[0]:
                best = (refined, q, outcome)
        self.configuration.update(best[1])
        return self._result(targets, iterations_total, time.perf_counter() - t0)

    def _clear_seed(self, q: np.ndarray) -> np.ndarray:
        """``q`` moved horizontally away from the obstacles it is inside (``SEED_BACKOFF`` steps, at
        most ``SEED_BACKOFF_MAX``). Why: the clearance limit only stops a pair from getting closer,
        so a start deep inside an object (the squat seed's knees in the box it picks up) stays
        there. The contact tasks then pull the limbs back to their targets with the limit active."""
        q = q.copy()
        for _ in range(int(round(SEED_BACKOFF_MAX / SEED_BACKOFF))):
            self.configuration.update(q)
            worst = self._deepest_obstacle()
            if worst is None:
                break
            away = self.configuration.data.body("pelvis").xpos[:2] - self.configuration.data.geom_xpos[worst][:2]
            if np.linalg.norm(away) < 1e-6:
                away = -frames.quat_to_matrix(q[3:7])[:2, 0]
            q[0:2] += SEED_BACKOFF * away / np.linalg.norm(away)
        return q

    def _deepest_obstacle(self) -> int | None:
        """The obstacle geom the current configuration is deepest inside (clearance not kept), or None."""
        distance, pair = self._closest_object_pair(OBJECT_CLEARANCE)
        return None if distance >= OBJECT_CLEARANCE else self._object_pairs[pair][1]

    def _closest_object_pair(self, reach: float) -> tuple[float, int]:
        """(signed distance m, index in ``_object_pairs``) of the closest robot-object pair within
        ``reach`` in the current configuration; (inf, -1) if none. Pairs are queried nearest bound
        first and the search stops where the bounds pass the best distance."""
        if not self._object_pairs:
            return float("inf"), -1
        model, data = self.model, self.configuration.data
        pairs = np.array([(r, g) for r, g, _ in self._object_pairs], dtype=int)
        gaps = _sphere_to_box_gaps(model, data, pairs[:, 0], pairs[:, 1])
        fromto = np.zeros(6)
        best, pair = float("inf"), -1
        for i in np.argsort(gaps, kind="stable"):
            if gaps[i] >= min(best, reach):
                break
            d = mujoco.mj_geomDistance(model, data, pairs[i, 0], pairs[i, 1], reach, fromto)
            if d < min(best, reach):
                best, pair = float(d), int(i)
        return best, pair

    def _seed(self, name: str, feet: list[LimbTarget], base_R: np.ndarray) -> np.ndarray:
        q = self.stand.copy()
        if name in _CROUCH_SEEDS:
            height, waist, shoulder_pitch, shoulder_roll = _CROUCH_SEEDS[name]
            for side, sign in (("left", 1.0), ("right", -1.0)):
                for joint, v in (*_SQUAT_LEGS, ("shoulder_pitch", shoulder_pitch),
                                 ("shoulder_roll", sign * shoulder_roll), ("elbow", 0.3)):
                    q[7 + G1_JOINT_NAMES.index(f"{side}_{joint}_joint")] = v
            q[7 + G1_JOINT_NAMES.index("waist_pitch_joint")] = waist
        elif name == "squat":
            for side in ("left", "right"):
                for joint, v in (*_SQUAT_LEGS, ("shoulder_pitch", -0.6)):
                    q[7 + G1_JOINT_NAMES.index(f"{side}_{joint}_joint")] = v
            q[7 + G1_JOINT_NAMES.index("waist_pitch_joint")] = 0.4
        elif name == "reach_up":
            for side in ("left", "right"):
                q[7 + G1_JOINT_NAMES.index(f"{side}_shoulder_pitch_joint")] = -2.2
        height = _CROUCH_SEEDS[name][0] if name in _CROUCH_SEEDS else \
            {"stand": self.stand[2], "squat": 0.45, "reach_up": self.stand[2]}[name]
        if feet:   # start above the feet, facing the right way
            mid = np.mean([t.position for t in feet], axis=0)
            q[0:3] = [mid[0], mid[1], mid[2] + height]
            q[3:7] = frames.matrix_to_quat(base_R)
        return q

    def _descend(self, target: RetargetTarget, targets: dict[str, LimbTarget], base_R: np.ndarray,
                 feet: list[LimbTarget], q0: np.ndarray, max_iterations: int) -> tuple[np.ndarray, DescentResult]:
        self.configuration.update(q0)

        tasks: list[mink.Task] = [self.base_task, self.posture_task]
        self.base_task.set_target(mink.SE3.from_rotation_and_translation(
            mink.SO3(frames.matrix_to_quat(base_R)), np.zeros(3)))
        if target.pelvis_height_ratio is not None and feet:   # a soft floor under the pelvis
            pelvis_z = float(np.mean([t.position[2] for t in feet])) + target.pelvis_height_ratio * self.leg_length
            tasks.append(PelvisFloorTask(pelvis_z, PELVIS_HEIGHT_COST))
            if PELVIS_HEIGHT_BAND is not None:   # and a ceiling well above it
                tasks.append(PelvisFloorTask(-np.inf, PELVIS_CEILING_COST, pelvis_z + PELVIS_HEIGHT_BAND * self.leg_length))
        posture = self.stand.copy()
        for name, angle in target.joint_prior.items():
            if name not in G1_JOINT_NAMES:
                raise RetargetingError(INVALID_REQUEST, f"joint prior names unknown G1 joint {name!r}")
            posture[7 + G1_JOINT_NAMES.index(name)] = float(angle)
        self.posture_task.set_target(posture)
        for limb, t in targets.items():
            task = self.limb_tasks[limb]
            if limb in FEET:
                task.set_position_cost(self._foot_position_cost(target, t))
            else:   # with sliding feet the hands are what the keyframe is about
                task.set_position_cost(1000.0 if self._sliding else 100.0)
            R = self._limb_rotation(limb, t, base_R, target.feet_pitch)
            p = t.position + (self.sole_offset * t.normal / np.linalg.norm(t.normal) if limb in FEET else 0.0)
            task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(frames.matrix_to_quat(R)), p))
            tasks.append(task)
        if len(feet) == 2:   # balance over where the feet are (they may slide)
            self.com_task.set_load(target.load_mass, target.load_point)
            self.com_task.cost = np.full(2, float(target.balance_cost))
            tasks.append(self.com_task)
        if self._clearance_task is not None:
            tasks.append(self._clearance_task)
        outcome = minimise(self.configuration, tasks, self._limits, solver=self.solver,
                           max_iterations=max_iterations, stall_window=IK_STALL_WINDOW,
                           stall_tolerance=IK_STALL_TOLERANCE)
        return self.configuration.q.copy(), outcome

    @staticmethod
    def _foot_position_cost(target: RetargetTarget, t: LimbTarget) -> np.ndarray:
        slide = target.floor_feet_slide and t.object_id in ("", "floor")
        return np.array([1.0, 1.0, 1000.0]) if slide else np.full(3, 1000.0)

    def _check(self, target: RetargetTarget) -> dict[str, LimbTarget]:
        targets: dict[str, LimbTarget] = {}
        for t in target.limb_targets:
            if t.limb not in LIMBS:
                raise RetargetingError(INVALID_REQUEST, f"unknown limb {t.limb!r}; valid: {', '.join(LIMBS)}")
            if t.limb in targets:
                raise RetargetingError(INVALID_REQUEST, f"limb {t.limb} has two targets")
            pos = _finite(t.position, 3, f"{t.limb} target position")
            normal = _finite(t.normal, 3, f"{t.limb} surface normal")
            if np.linalg.norm(normal) < 1e-9:
                raise RetargetingError(INVALID_REQUEST, f"{t.limb} surface normal is zero")
            targets[t.limb] = LimbTarget(t.limb, pos, normal / np.linalg.norm(normal), t.object_id)
        # the IK's tasks follow this order: keep it fixed so the same targets give the same keyframe
        targets = {limb: targets[limb] for limb in LIMBS if limb in targets}
        if not any(limb in targets for limb in FEET):
            raise RetargetingError(INVALID_REQUEST, "a keyframe needs at least one foot in contact")
        if target.base_orientation_wxyz is not None:
            _finite(target.base_orientation_wxyz, 4, "base orientation")
        return targets

    @staticmethod
    def _base_rotation(target: RetargetTarget, feet: list[LimbTarget]) -> np.ndarray:
        if target.base_orientation_wxyz is not None:
            q = np.asarray(target.base_orientation_wxyz, float)
            return frames.quat_to_matrix(q / np.linalg.norm(q))
        return np.eye(3)

    @staticmethod
    def _limb_rotation(limb: str, t: LimbTarget, base_R: np.ndarray, feet_pitch: float) -> np.ndarray:
        if limb not in FEET:
            return np.eye(3)
        # Sole z along the surface normal, sole x along the base heading projected on the surface.
        z = t.normal
        x = base_R[:, 0] - np.dot(base_R[:, 0], z) * z
        if np.linalg.norm(x) < 1e-6:
            x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        if feet_pitch:
            c, s = np.cos(feet_pitch), np.sin(feet_pitch)
            R = R @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        return R

    def sole_points(self, points: np.ndarray) -> np.ndarray:
        """``points`` (N x 3, in the foot site's body frame: the ankle-roll link) of both feet in the
        world at the current configuration, left foot's first (2N x 3)."""
        data = self.configuration.data
        world = []
        for foot in FEET:
            body = int(self.model.site_bodyid[self.model.site(foot).id])
            world.append(data.xpos[body] + np.asarray(points, float) @ data.xmat[body].reshape(3, 3).T)
        return np.concatenate(world)

    def support_margin(self, sole_points: np.ndarray, load_mass: float = 0.0,
                       load_point: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """(signed margin m, outward normal) of the robot-and-load CoM in the current configuration's
        support polygon: both feet's ``sole_points`` (:meth:`sole_points`) projected on the floor
        plane. See :func:`balance.support_margin`."""
        data = self.configuration.data
        com = combined_com(float(self.model.body_subtreemass[1]), data.subtree_com[1], load_mass, load_point)
        return support_margin(com, convex_hull(self.sole_points(sole_points)))

    def _min_self_distance(self) -> float:
        """Smallest signed distance over the self-collision pairs (m) in the current configuration."""
        model, data = self.model, self.configuration.data
        fromto = np.zeros(6)
        return float(min(mujoco.mj_geomDistance(model, data, a, b, 0.1, fromto)
                         for a_list, b_list in self._pairs for a in a_list for b in b_list))

    def _min_object_distance(self) -> tuple[float, str]:
        """Smallest signed distance over this solve's robot-object pairs (m; inf without any within
        10 m) and "robot body vs object" for it, in the current configuration."""
        distance, pair = self._closest_object_pair(10.0)
        if pair < 0:
            return distance, ""
        robot, _, object_id = self._object_pairs[pair]
        return distance, f"{self.model.body(self.model.geom_bodyid[robot]).name} vs {object_id}"

    def _residuals(self, targets: dict[str, LimbTarget]) -> dict[str, float]:
        out = {}
        for limb, t in targets.items():
            p = self.configuration.get_transform_frame_to_world(limb, "site").translation()
            goal = t.position + (self.sole_offset * t.normal if limb in FEET else 0.0)
            err = p - goal
            if limb in self._sliding:
                err = np.dot(err, t.normal) * t.normal   # a sliding foot only has to stay on its surface
            out[limb] = float(np.linalg.norm(err))
        return out

    def _result(self, targets: dict[str, LimbTarget], iterations: int, seconds: float) -> RetargetResult:
        model, data = self.model, self.configuration.data
        q = self.configuration.q.copy()
        residuals = self._residuals(targets)
        tilt = {}
        for limb, t in targets.items():
            if limb in FEET:
                z = data.site(limb).xmat.reshape(3, 3)[:, 2]
                tilt[limb] = float(np.arccos(np.clip(np.dot(z, t.normal), -1.0, 1.0)))
        lo, hi = model.jnt_range[1:, 0], model.jnt_range[1:, 1]
        within = bool(np.all(q[7:] >= lo - 1e-6) and np.all(q[7:] <= hi + 1e-6))
        min_dist = self._min_self_distance()
        points = {}
        for limb, t in targets.items():
            p = data.site(limb).xpos.copy()
            points[limb] = p - self.sole_offset * t.normal if limb in FEET else p
        object_dist, closest = self._min_object_distance()
        result = RetargetResult(q, residuals, tilt, float(min_dist), within, iterations, seconds, points,
                                object_dist, closest)
        worst = max(residuals, key=residuals.get)
        if residuals[worst] > self.contact_tolerance:
            raise RetargetingError(RETARGETING_INFEASIBLE,
                                   f"{worst} cannot reach its contact on {targets[worst].object_id}: "
                                   f"{residuals[worst] * 100:.1f} cm away after {iterations} IK iterations")
        if not within:
            raise RetargetingError(RETARGETING_INFEASIBLE, "IK left a joint outside its limits")
        if min_dist < 0.0:
            raise RetargetingError(RETARGETING_INFEASIBLE, f"self-collision ({min_dist * 1000:.1f} mm)")
        if object_dist < -OBJECT_PENETRATION_TOLERANCE:
            raise RetargetingError(RETARGETING_INFEASIBLE,
                                   f"{closest.replace(' vs ', ' is inside ')} by {-object_dist * 1000:.1f} mm")
        return result
