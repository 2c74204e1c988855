"""The TO result: knot values, a dense time grid for a controller, solver statistics.

Everything a ``lomanip_msgs/WholeBodyTrajectory`` needs is here (no ROS types): joint names, dense
time grid, base poses (quaternion x,y,z,w) and twists, 29 joint positions/velocities, object poses,
contact wrenches per point per limb (acting ON the robot, world frame, about the contact point),
CoM and centroidal momentum, and :class:`SolverStats` (converged, iterations, times, worst
dynamics/contact violation with time and constraint name, max penetration, peak memory).

A failed solve is reported as failed: ``stats.converged`` is False and ``stats.success`` False;
the numbers are still returned for diagnosis but must not be executed.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field

import numpy as np

from .model import rot_to_quat_xyzw, rpy_rate_matrix, rpy_to_rot

#: status of a final stage stopped by the stall acceptance (Options.stall_iterations): the best
#: feasible iterate stopped improving; the stage returns it.  Measured on S1's carry (subtask
#: 1): ipopt's dual infeasibility kept jumping between 2e-3 and 3e2 from one iteration to the next
#: while the objective crept from 73.15 to 73.00 in 150 iterations at violation <= 5e-6, so neither
#: its tolerance nor its acceptable test (10 acceptable iterations in a row) was ever met.
STALLED_STATUS = "Feasible_Objective_Stalled"
#: status of a final stage that reached its iteration cap on a feasible iterate and returned the best
#: one (Options.accept_feasible_at_cap)
CAPPED_FEASIBLE_STATUS = "Feasible_At_Iteration_Cap"
#: status of a final stage that ipopt itself stopped without optimality (STOPPED_EARLY_STATUSES) after
#: it had passed through a feasible iterate; the stage returns the best one
#: (Options.accept_feasible_at_solver_stop)
FEASIBLE_BEFORE_STOP_STATUS = "Feasible_Before_Solver_Stop"
#: ipopt's return statuses for a run it ended by itself before its optimality test was met. Why:
#: S2 5.0 kg at yaw +-0.6 (session 40): the pick's final stage ended "Infeasible_Problem_Detected" (its
#: restoration phase gave up) on a point within 5e-6 / 7e-6 of every row, and the whole plan failed there
STOPPED_EARLY_STATUSES = ("Infeasible_Problem_Detected", "Restoration_Failed",
                          "Search_Direction_Becomes_Too_Small", "Error_In_Step_Computation")


@dataclass
class Violation:
    value: float = 0.0
    time: float = 0.0
    constraint: str = ""

    def text(self) -> str:
        return f"{self.value:.2e} at t={self.time:.2f} s, {self.constraint}" if self.constraint else f"{self.value:.2e}"


@dataclass
class Progress:
    """One ipopt iteration, as reported to ``solve(..., progress=callback)``."""

    iteration: int  # counted over all stages and segments of the solve
    objective: float
    constraint_violation: float  # max over rows (bounds included), unscaled
    stage: str  # e.g. "subtask 1 (3.0-11.4 s) surrogate guide", "whole-horizon polish final"
    elapsed: float  # s since solve() started

    def text(self) -> str:
        return (f"iter {self.iteration:4d}  obj {self.objective:.4e}  viol {self.constraint_violation:.2e}  "
                f"{self.elapsed:6.1f} s  [{self.stage}]")


@dataclass
class SolverStats:
    solver: str = "ipopt (window-assembled exact derivatives)"
    converged: bool = False
    status: str = ""
    iterations: int = 0
    build_time: float = 0.0
    solve_time: float = 0.0
    cost: float = float("nan")
    max_dynamics_violation: Violation = field(default_factory=Violation)
    max_contact_violation: Violation = field(default_factory=Violation)
    max_constraint_violation: Violation = field(default_factory=Violation)
    max_penetration: float = 0.0
    max_penetration_time: float = 0.0
    peak_memory_mb: float = 0.0
    n_knots: int = 0
    n_variables: int = 0
    n_constraints: int = 0
    stages: list = field(default_factory=list)
    checks: dict = field(default_factory=dict)
    success: bool = False  # converged AND the physical checks pass

    def status_message(self) -> str:
        """One line; a failure names the worst violated constraint with its time."""
        pen = f"max penetration {self.max_penetration * 1e3:.1f} mm at t={self.max_penetration_time:.2f} s"
        if self.converged:
            how = "converged"
            if STALLED_STATUS in self.status:
                how = "converged to a feasible point whose objective stalled (ipopt's optimality test not met)"
            if CAPPED_FEASIBLE_STATUS in self.status:
                how = "stopped at the iteration cap on a feasible point (ipopt's optimality test not met)"
            if FEASIBLE_BEFORE_STOP_STATUS in self.status:
                how = ("kept the best feasible point from before ipopt stopped early (ipopt's optimality "
                       "test not met)")
            return f"{how} in {self.iterations} iterations; max constraint violation " \
                   f"{self.max_constraint_violation.text()}; {pen}"
        return (f"did not converge in {self.iterations} iterations ({self.status}); max constraint violation "
                f"{self.max_constraint_violation.text()}; {pen}")


@dataclass
class TOResult:
    joint_names: list
    limbs: list
    object_ids: list
    # knots
    t_knots: np.ndarray
    x_knots: np.ndarray  # K x 35  (base p, rpy, joints)
    xd_knots: np.ndarray  # K x 35
    com_knots: np.ndarray  # K x 3
    h_knots: np.ndarray  # K x 6 linear (kg m/s), angular about CoM (kg m^2/s)
    forces_knots: dict  # limb -> K x 3 (N, world, on the robot)
    torques_knots: dict  # limb -> K x 3 (N m about the contact point)
    points_knots: dict  # limb -> K x 3 contact point (world)
    corner_forces_knots: dict  # foot -> K x 4 x 3 (N)
    contact_objects_knots: dict  # limb -> list of object id ("" when not in contact)
    object_pose_knots: dict  # object id -> K x 6 (p, rpy)
    object_vel_knots: dict  # object id -> K x 6 (v, rpy rates)
    penetration_knots: np.ndarray  # K (sum of negative signed distances, positive metres)
    stats: SolverStats
    normals_knots: dict = None  # hand -> K x 3 outward surface normal of the touched object
    # dense grid (filled by densify)
    t: np.ndarray = None
    base_position: np.ndarray = None
    base_quat_xyzw: np.ndarray = None
    base_linear_velocity: np.ndarray = None  # world
    base_angular_velocity: np.ndarray = None  # world
    joint_positions: np.ndarray = None
    joint_velocities: np.ndarray = None
    com: np.ndarray = None
    linear_momentum: np.ndarray = None
    angular_momentum: np.ndarray = None
    forces: dict = None
    torques: dict = None
    points: dict = None
    contact_objects: dict = None
    object_positions: dict = None
    object_quat_xyzw: dict = None
    object_linear_velocity: dict = None
    object_angular_velocity: dict = None
    penetration: np.ndarray = None

    @property
    def success(self) -> bool:
        return bool(self.stats.success)

    # ------------------------------------------------------------------------------------------
    def densify(self, rate: float = 100.0) -> "TOResult":
        """Reconstruct a dense grid: C1 cubic Hermite through the knots for positions (slopes =
        mean of adjacent secant slopes, one-sided at a foot's lift-off and touchdown knots), its
        derivative for velocities, zero-order hold on the knot
        interval for contact wrenches (the transcription applies forces of knot k on [t_k, t_k+1))."""
        tk = self.t_knots
        n = int(np.floor((tk[-1] - tk[0]) * rate + 1e-9)) + 1
        t = tk[0] + np.arange(n) / rate
        if t[-1] < tk[-1] - 1e-9:
            t = np.append(t, tk[-1])
        self.t = t
        sides = _contact_sides(self.contact_objects_knots)
        X, Xd = _hermite(tk, self.x_knots, t, sides)
        self.base_position = X[:, :3]
        self.base_quat_xyzw = np.array([rot_to_quat_xyzw(rpy_to_rot(r)) for r in X[:, 3:6]])
        self.base_linear_velocity = Xd[:, :3]
        self.base_angular_velocity = np.array([rpy_rate_matrix(r) @ rd for r, rd in zip(X[:, 3:6], Xd[:, 3:6])])
        self.joint_positions = X[:, 6:]
        self.joint_velocities = Xd[:, 6:]
        self.com, _ = _hermite(tk, self.com_knots, t, sides)
        H, _ = _hermite(tk, self.h_knots, t, sides)
        self.linear_momentum, self.angular_momentum = H[:, :3], H[:, 3:]
        idx = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, len(tk) - 1)
        self.forces = {l: v[idx] for l, v in self.forces_knots.items()}
        self.torques = {l: v[idx] for l, v in self.torques_knots.items()}
        self.points = {l: v[idx] for l, v in self.points_knots.items()}
        self.contact_objects = {l: [v[i] for i in idx] for l, v in self.contact_objects_knots.items()}
        self.object_positions, self.object_quat_xyzw = {}, {}
        self.object_linear_velocity, self.object_angular_velocity = {}, {}
        for oid, pose in self.object_pose_knots.items():
            P, Pd = _hermite(tk, pose, t)
            self.object_positions[oid] = P[:, :3]
            self.object_quat_xyzw[oid] = np.array([rot_to_quat_xyzw(rpy_to_rot(r)) for r in P[:, 3:]])
            self.object_linear_velocity[oid] = Pd[:, :3]
            self.object_angular_velocity[oid] = np.array([rpy_rate_matrix(r) @ rd for r, rd in zip(P[:, 3:], Pd[:, 3:])])
        self.penetration = np.interp(t, tk, self.penetration_knots)
        return self

    def save(self, path) -> None:
        """Write the knot data, names and solver statistics to ``path`` (.npz, no pickles).  The
        dense grid is not stored: :meth:`load` rebuilds it with :meth:`densify` at the same rate."""
        _save(self, path)

    @staticmethod
    def load(path) -> "TOResult":
        """Read a result written by :meth:`save` (densified, ``data`` is not restored)."""
        return _load(path)

    def summary(self) -> dict:
        s = asdict(self.stats)
        s["duration"] = float(self.t_knots[-1])
        return s

    def to_json(self) -> str:
        d = {"stats": self.summary(), "t_knots": self.t_knots.tolist(),
             "x_knots": self.x_knots.tolist(), "penetration_knots": self.penetration_knots.tolist(),
             "joint_names": self.joint_names,
             "object_pose_knots": {k: v.tolist() for k, v in self.object_pose_knots.items()},
             "forces_knots": {k: v.tolist() for k, v in self.forces_knots.items()}}
        return json.dumps(d)


#: TOResult fields saved by :meth:`TOResult.save` (knot data; the dense grid is rebuilt on load)
_KNOT_ARRAYS = ("t_knots", "x_knots", "xd_knots", "com_knots", "h_knots", "penetration_knots")
_KNOT_DICTS = ("forces_knots", "torques_knots", "points_knots", "corner_forces_knots", "object_pose_knots",
               "object_vel_knots", "normals_knots")
_FORMAT = "lomanip_to.TOResult/1"


def _save(res: TOResult, path) -> None:
    arrays = {f"a/{k}": np.asarray(getattr(res, k), float) for k in _KNOT_ARRAYS}
    for name in _KNOT_DICTS:
        for key, v in (getattr(res, name) or {}).items():
            arrays[f"d/{name}/{key}"] = np.asarray(v, float)
    rate = 100.0
    if res.t is not None and len(res.t) > 1:
        rate = float(round(1.0 / (res.t[1] - res.t[0]), 6))
    meta = {"format": _FORMAT, "joint_names": list(res.joint_names), "limbs": list(res.limbs),
            "object_ids": list(res.object_ids), "output_rate": rate,
            "contact_objects_knots": {k: list(v) for k, v in res.contact_objects_knots.items()},
            "stats": asdict(res.stats)}
    arrays["meta"] = np.array(json.dumps(meta, default=_json_default))
    with open(path, "wb") as fh:  # a file object: np.savez would otherwise append ".npz"
        np.savez_compressed(fh, **arrays)


def _load(path) -> TOResult:
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        if meta.get("format") != _FORMAT:
            raise ValueError(f"{path}: not a saved TOResult (format {meta.get('format')!r})")
        kw = {k: z[f"a/{k}"] for k in _KNOT_ARRAYS}
        for name in _KNOT_DICTS:
            pre = f"d/{name}/"
            kw[name] = {k[len(pre):]: z[k] for k in z.files if k.startswith(pre)}
    st = dict(meta["stats"])
    for v in ("max_dynamics_violation", "max_contact_violation", "max_constraint_violation"):
        st[v] = Violation(**st[v])
    res = TOResult(joint_names=meta["joint_names"], limbs=meta["limbs"], object_ids=meta["object_ids"],
                   contact_objects_knots=meta["contact_objects_knots"], stats=SolverStats(**st), **kw)
    return res.densify(meta["output_rate"])


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def _contact_sides(contact_objects_knots: dict, feet=("left_foot", "right_foot")) -> np.ndarray:
    """Per knot: -1 at a foot's lift-off knot, +1 at its touchdown knot, 0 elsewhere.

    Why: with mean-secant slopes the interpolant of a knot where a foot lifts off already carries the
    swing velocity into the interval before it, so the dense plan slid a loaded foot (S1: 0.3 m/s
    sideways while in double support) and started its swing with a kick.  Taking the secant of the
    planted interval keeps the foot still over that interval and starts (ends) the swing at rest.
    """
    K = len(next(iter(contact_objects_knots.values()))) if contact_objects_knots else 0
    sides = np.zeros(K, int)
    for f in feet:
        c = contact_objects_knots.get(f)
        if c is None:
            continue
        for k in range(1, K - 1):
            if c[k - 1] and not c[k]:  # last force at k-1 acts until k: planted over [k-1, k]
                sides[k] = -1
            elif not c[k] and c[k + 1] and sides[k + 1] == 0:  # lands at k+1: planted from k+1
                sides[k + 1] = 1
    return sides


def _hermite(tk: np.ndarray, Y: np.ndarray, t: np.ndarray, sides: np.ndarray | None = None):
    """C1 cubic Hermite interpolation (values and derivatives) of rows Y at knots tk.

    The slope at a knot is the mean of the adjacent secants, or with ``sides[k]`` = -1 / +1 the
    secant of the interval before / after it alone (see :func:`_contact_sides`)."""
    Y = np.asarray(Y, float)
    K = len(tk)
    if K == 1:
        return np.repeat(Y, len(t), 0), np.zeros((len(t), Y.shape[1]))
    sec = np.diff(Y, axis=0) / np.diff(tk)[:, None]
    m = np.zeros_like(Y)
    m[0], m[-1] = sec[0], sec[-1]
    m[1:-1] = 0.5 * (sec[:-1] + sec[1:])
    if sides is not None:
        for k in range(1, K - 1):
            if sides[k] < 0:
                m[k] = sec[k - 1]
            elif sides[k] > 0:
                m[k] = sec[k]
    i = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, K - 2)
    h = (tk[i + 1] - tk[i])[:, None]
    s = ((t - tk[i])[:, None]) / h
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    val = h00 * Y[i] + h10 * h * m[i] + h01 * Y[i + 1] + h11 * h * m[i + 1]
    d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    der = (d00 * Y[i] + d01 * Y[i + 1]) / h + d10 * m[i] + d11 * m[i + 1]
    return val, der
