"""Whole-body trajectory to execute: a ROS-free copy of ``lomanip_msgs/WholeBodyTrajectory``.

Why: the whole-body controller, the executor, the benchmark and the tests all need the plan as
plain arrays on one time grid (joint order = G1_JOINT_NAMES, MuJoCo quaternion order w,x,y,z),
and they must reject a bad plan with a clear code before anything moves. Three kinds of checks:

* structure (:func:`make_trajectory`): joint names of the G1 (any order, reordered here), a time
  grid that starts at 0 and strictly increases, consistent array lengths, finite numbers;
* scene (:func:`check_against_scene`): contacts and object trajectories name objects of the world;
* start (:func:`check_start`): the first point is close to the robot's current state.

Builders: :func:`from_to_result` (a densified ``lomanip_to`` TOResult + its contact phases, duck
typed so this module does not import lomanip_to) and ``conversions.trajectory_from_msg``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import frames
from .robot_model import G1_JOINT_NAMES

# Error codes: same values as lomanip_msgs/ErrorCode (checked in tests/sim/test_trajectory.py).
INVALID_REQUEST = -1
UNKNOWN_OBJECT = -2
INVALID_TRAJECTORY = -11
EXECUTION_FAILED = -12

ROBOT_NAME = "unitree_g1_29dof_rev_1_0"
LIMBS = ("left_foot", "right_foot", "left_hand", "right_hand")
FEET = ("left_foot", "right_foot")
HANDS = ("left_hand", "right_hand")
FLOOR = "floor"


class TrajectoryError(ValueError):
    """A trajectory that must not be executed; ``code`` is a lomanip_msgs/ErrorCode value."""

    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code
        self.message = message


@dataclass(frozen=True)
class LimbContact:
    """One limb touching ``object_id`` ("floor" or a scene object) at ``position`` (None: free)."""

    object_id: str
    position: np.ndarray | None
    normal: np.ndarray  # outward surface normal of the touched object, world frame


@dataclass(frozen=True)
class Phase:
    """A contact phase of the schedule: which limbs touch what, from start to end (s)."""

    start: float
    end: float
    contacts: dict[str, LimbContact]
    walking: bool = False
    #: objects the plan has carried by the robot's contacts alone in this phase (ObjectMotion "free");
    #: None: the schedule does not say (then the controller judges from the object's planned height)
    free_objects: frozenset[str] | None = None


@dataclass
class Trajectory:
    """The plan on one time grid ``t`` (N points, t[0] = 0, strictly increasing)."""

    t: np.ndarray  # (N,)
    q: np.ndarray  # (N, 29) joint positions, G1_JOINT_NAMES order
    qd: np.ndarray  # (N, 29)
    base_pos: np.ndarray  # (N, 3) pelvis position, world
    base_quat: np.ndarray  # (N, 4) pelvis orientation (w, x, y, z)
    base_linvel: np.ndarray  # (N, 3) world
    base_angvel: np.ndarray  # (N, 3) world
    phases: list[Phase] = field(default_factory=list)
    #: planned wrench ON the robot per limb, world frame, about the contact point (zeros = no contact)
    forces: dict[str, np.ndarray] = field(default_factory=dict)  # limb -> (N, 3)
    torques: dict[str, np.ndarray] = field(default_factory=dict)  # limb -> (N, 3)
    objects: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)  # id -> (pos (N,3), quat wxyz (N,4))
    scenario: str = ""
    robot_name: str = ROBOT_NAME
    #: planned centroidal angular momentum about the CoM (N, 3), kg m^2/s, or None (not given)
    angular_momentum: np.ndarray | None = None
    #: planned contact point per limb (N, 3), world, where its wrench acts; NaN rows = not touching
    #: (the controller reads the hands' planned distance from the surface off it)
    points: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def n(self) -> int:
        return len(self.t)

    def qpos(self, i: int) -> np.ndarray:
        """36-D MuJoCo configuration of the robot at point i."""
        return np.concatenate([self.base_pos[i], self.base_quat[i], self.q[i]])

    def qvel(self, i: int) -> np.ndarray:
        """35-D MuJoCo velocity at point i (free joint: world linear, body-frame angular)."""
        R = frames.quat_to_matrix(self.base_quat[i])
        return np.concatenate([self.base_linvel[i], R.T @ self.base_angvel[i], self.qd[i]])

    def phase_at(self, t: float) -> Phase | None:
        """The contact phase active at time t (the last one after the end); None if no schedule."""
        if not self.phases:
            return None
        for ph in self.phases:
            if ph.start - 1e-9 <= t < ph.end:
                return ph
        return self.phases[-1] if t >= self.phases[-1].end else self.phases[0]

    def index_at(self, t: float) -> tuple[int, float]:
        """(i, s): t lies between points i and i+1 at fraction s (clamped to the grid)."""
        if t <= self.t[0]:
            return 0, 0.0
        if t >= self.t[-1]:
            return self.n - 2, 1.0
        i = int(np.searchsorted(self.t, t, side="right")) - 1
        return i, float((t - self.t[i]) / (self.t[i + 1] - self.t[i]))

    def contact_object_ids(self) -> set[str]:
        return {c.object_id for ph in self.phases for c in ph.contacts.values()}


def _arr(x, shape_tail: tuple[int, ...], n: int, what: str) -> np.ndarray:
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as e:
        raise TrajectoryError(INVALID_TRAJECTORY, f"{what}: not numeric ({e})") from None
    if a.shape != (n, *shape_tail):
        raise TrajectoryError(INVALID_TRAJECTORY, f"{what}: expected shape {(n, *shape_tail)}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        i = int(np.argwhere(~np.isfinite(a))[0][0])
        raise TrajectoryError(INVALID_TRAJECTORY, f"{what}: NaN or inf at point {i}")
    return a


def check_joint_names(names) -> np.ndarray:
    """Index array that reorders ``names`` into G1_JOINT_NAMES order; raises on a mismatch."""
    names = list(names)
    missing = [j for j in G1_JOINT_NAMES if j not in names]
    unknown = [j for j in names if j not in G1_JOINT_NAMES]
    dup = len(set(names)) != len(names)
    if missing or unknown or dup:
        parts = []
        if unknown:
            parts.append(f"unknown {unknown[:3]}{'...' if len(unknown) > 3 else ''}")
        if missing:
            parts.append(f"missing {missing[:3]}{'...' if len(missing) > 3 else ''}")
        if dup:
            parts.append("duplicate names")
        raise TrajectoryError(INVALID_TRAJECTORY, "joint names do not match the Unitree G1 (29 DoF, rev 1.0): "
                              + ", ".join(parts) + " (a trajectory for another robot?)")
    return np.array([names.index(j) for j in G1_JOINT_NAMES])


def check_time_grid(t) -> np.ndarray:
    """The time grid as floats: at least 2 points, finite, starts at 0, strictly increasing."""
    t = np.asarray(t, dtype=float).reshape(-1)
    n = len(t)
    if n < 2:
        raise TrajectoryError(INVALID_TRAJECTORY, f"trajectory needs at least 2 points, got {n}")
    if not np.all(np.isfinite(t)):
        raise TrajectoryError(INVALID_TRAJECTORY, "time_from_start contains NaN/inf")
    dt = np.diff(t)
    if np.any(dt <= 0):
        i = int(np.argmax(dt <= 0)) + 1
        raise TrajectoryError(INVALID_TRAJECTORY, f"time grid does not increase: point {i} at t={t[i]:.4f} s "
                              f"follows t={t[i - 1]:.4f} s")
    if abs(t[0]) > 1e-6:
        raise TrajectoryError(INVALID_TRAJECTORY, f"time grid must start at 0, starts at {t[0]:.4f} s")
    return t


def make_trajectory(t, joint_names, q, qd, base_pos, base_quat_wxyz, base_linvel=None, base_angvel=None, *,
                    phases=(), forces=None, torques=None, objects=None, scenario: str = "",
                    robot_name: str = ROBOT_NAME, angular_momentum=None, points=None) -> Trajectory:  # fmt: skip
    """Check and build a Trajectory (joint columns reordered into G1 order). Raises TrajectoryError."""
    if robot_name and robot_name != ROBOT_NAME:
        raise TrajectoryError(INVALID_TRAJECTORY, f"trajectory is for robot {robot_name!r}, this sim runs {ROBOT_NAME!r}")
    t = check_time_grid(t)
    n = len(t)
    order = check_joint_names(joint_names)
    q = _arr(q, (len(order),), n, "joint positions")[:, order]
    qd = _arr(qd, (len(order),), n, "joint velocities")[:, order] if qd is not None else np.gradient(q, t, axis=0)
    base_pos = _arr(base_pos, (3,), n, "base positions")
    quat = _arr(base_quat_wxyz, (4,), n, "base orientations")
    norms = np.linalg.norm(quat, axis=1)
    if np.any(norms < 1e-6):
        raise TrajectoryError(INVALID_TRAJECTORY, f"zero base quaternion at point {int(np.argmin(norms))}")
    quat = quat / norms[:, None]
    lin = _arr(base_linvel, (3,), n, "base linear velocities") if base_linvel is not None else np.gradient(base_pos, t, axis=0)
    ang = _arr(base_angvel, (3,), n, "base angular velocities") if base_angvel is not None else np.zeros((n, 3))
    fz = {l: _arr(v, (3,), n, f"{l} forces") for l, v in (forces or {}).items()}
    tz = {l: _arr(v, (3,), n, f"{l} torques") for l, v in (torques or {}).items()}
    pz = {}
    for l, v in (points or {}).items():
        v = np.asarray(v, float)
        if v.shape != (n, 3):
            raise TrajectoryError(INVALID_TRAJECTORY, f"{l} contact points: expected shape ({n}, 3), got {v.shape}")
        pz[l] = v
    for limb in list(fz) + list(tz) + list(pz):
        if limb not in LIMBS:
            raise TrajectoryError(INVALID_TRAJECTORY, f"unknown limb {limb!r} in contact wrenches (valid: {LIMBS})")
    objs = {}
    for oid, (p, qq) in (objects or {}).items():
        p = _arr(p, (3,), n, f"object {oid} positions")
        qq = _arr(qq, (4,), n, f"object {oid} orientations")
        objs[oid] = (p, qq / np.maximum(np.linalg.norm(qq, axis=1), 1e-9)[:, None])
    angmom = _arr(angular_momentum, (3,), n, "angular momenta") if angular_momentum is not None else None
    phases = list(phases)
    for k, ph in enumerate(phases):
        if ph.end < ph.start:
            raise TrajectoryError(INVALID_TRAJECTORY, f"contact phase {k} ends ({ph.end:.3f} s) before it starts")
        if k and ph.start < phases[k - 1].start:
            raise TrajectoryError(INVALID_TRAJECTORY, f"contact phase {k} starts before phase {k - 1}")
        for limb in ph.contacts:
            if limb not in LIMBS:
                raise TrajectoryError(INVALID_TRAJECTORY, f"unknown limb {limb!r} in contact phase {k}")
    return Trajectory(t=t, q=q, qd=qd, base_pos=base_pos, base_quat=quat, base_linvel=lin, base_angvel=ang,
                      phases=phases, forces=fz, torques=tz, objects=objs, scenario=scenario, robot_name=robot_name,
                      angular_momentum=angmom, points=pz)


def check_against_scene(traj: Trajectory, object_ids) -> None:
    """Every object the plan touches or moves must exist in the world (else UNKNOWN_OBJECT)."""
    known = set(object_ids) | {FLOOR}
    for oid in sorted(traj.contact_object_ids() | set(traj.objects)):
        if oid not in known:
            raise TrajectoryError(UNKNOWN_OBJECT, f"trajectory refers to object {oid!r}, which is not in the "
                                  f"simulated world (objects: {', '.join(sorted(known))})")


@dataclass(frozen=True)
class StartTolerance:
    """How far the first trajectory point may be from the robot's current state."""

    base_position: float = 0.15  # m
    base_angle: float = 0.35  # rad (rotation angle between the pelvis orientations)
    joint: float = 0.6  # rad, any single joint


def check_start(traj: Trajectory, robot_qpos: np.ndarray, tol: StartTolerance | None = None) -> None:
    """Raise INVALID_TRAJECTORY when the plan starts far from the current 36-D robot configuration."""
    tol = tol or StartTolerance()
    dp = float(np.linalg.norm(traj.base_pos[0] - robot_qpos[0:3]))
    if dp > tol.base_position:
        raise TrajectoryError(INVALID_TRAJECTORY, f"trajectory starts {dp:.2f} m from the robot's current base "
                              f"position (tolerance {tol.base_position:.2f} m): plan from the current state")
    qa = frames.quat_multiply(frames.quat_conjugate(robot_qpos[3:7] / np.linalg.norm(robot_qpos[3:7])), traj.base_quat[0])
    ang = 2.0 * float(np.arccos(np.clip(abs(qa[0]), -1.0, 1.0)))
    if ang > tol.base_angle:
        raise TrajectoryError(INVALID_TRAJECTORY, f"trajectory starts with the pelvis rotated {ang:.2f} rad from the "
                              f"robot's current orientation (tolerance {tol.base_angle:.2f} rad)")
    dq = np.abs(traj.q[0] - robot_qpos[7:36])
    j = int(np.argmax(dq))
    if dq[j] > tol.joint:
        raise TrajectoryError(INVALID_TRAJECTORY, f"trajectory starts {dq[j]:.2f} rad from the current position of "
                              f"{G1_JOINT_NAMES[j]} (tolerance {tol.joint:.2f} rad)")


def phases_from_to(phases) -> list[Phase]:
    """lomanip_to ContactPhase list (duck typed) -> Phase list."""
    out = []
    for ph in phases:
        contacts = {}
        for limb, c in ph.contacts.items():
            pos = None if c.position is None else np.asarray(c.position, float)
            contacts[limb] = LimbContact(c.object_id, pos, np.asarray(c.normal, float))
        motions = getattr(ph, "objects", None)
        free = None if motions is None else frozenset(o for o, mo in motions.items() if str(mo.mode) == "free")
        out.append(Phase(float(ph.start), float(ph.end), contacts, walking=(str(ph.phase_type) == "walking"),
                         free_objects=free))
    return out


def from_to_result(res, phases, scenario: str = "") -> Trajectory:
    """A densified lomanip_to TOResult (+ its problem's contact phases) -> Trajectory."""
    if getattr(res, "t", None) is None:
        res.densify()
    quat = np.array([frames.xyzw_to_wxyz(q) for q in res.base_quat_xyzw])
    forces, torques, points = {}, {}, {}
    for limb, f in (res.forces or {}).items():
        active = np.array([bool(o) for o in res.contact_objects[limb]])
        forces[limb] = np.where(active[:, None], f, 0.0)
        torques[limb] = np.where(active[:, None], res.torques[limb], 0.0)
        if limb in (getattr(res, "points", None) or {}):
            points[limb] = np.where(active[:, None], res.points[limb], np.nan)
    objects = {oid: (res.object_positions[oid], np.array([frames.xyzw_to_wxyz(q) for q in res.object_quat_xyzw[oid]]))
               for oid in (res.object_positions or {})}
    t = np.asarray(res.t, float) - float(res.t[0])
    return make_trajectory(t, res.joint_names, res.joint_positions, res.joint_velocities, res.base_position, quat,
                           res.base_linear_velocity, res.base_angular_velocity, phases=phases_from_to(phases),
                           forces=forces, torques=torques, objects=objects, scenario=scenario,
                           angular_momentum=res.angular_momentum, points=points)  # fmt: skip
