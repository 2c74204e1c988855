"""Discretisation: from a :class:`~lomanip_to.problem.Problem` to numbers: knot grid, bounds, parameters, warm start.

Phase-wise sizing: each contact phase is split into knots at ``dt_stance`` / ``dt_walking``; knot
k belongs to the phase containing [t_k, t_{k+1}).  Everything here is numpy; the symbolic side lives
in ``transcription.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .model import FEET, HANDS, SOLE_CENTER, G1Model, rot_to_rpy, rpy_to_rot, sole_force_points
from .problem import FLOOR, INVALID_REQUEST, STANCE, WALKING, Problem, ProblemError, SceneObject
from .route import footprint_of, point_along, shortest_route, smoothstep, walking_heading
from .transcription import UPPER_BODY_XD, G, Structure, Window, grip_axes

INF = np.inf
#: clearance (m) of the foot and shin spheres from objects in the hard collision rows.  Why: the
#: spheres only approximate the meshes (a toe corner sticks out ~5 mm past the toe spheres, the
#: kneecap past the shin's), and the demo push's plans stepped a toe into a trolley wheel and a
#: knee against its deck on MuJoCo's model; the executed robot fell (docs/execution.md, session 8)
LEG_OBJECT_CLEARANCE = 0.03
#: m: radius of the point spheres that stand for a carried object in its clearance rows from the
#: other objects (inset by it, so a sphere touches the object's face: the distance is smooth there)
CARRIED_POINT_RADIUS = 0.01
#: s over which a carried object's nominal comes in to Options.carry_reach (and back out)
CARRY_REACH_BLEND = 0.8
#: m the object's nominal rises by meanwhile, so that, drawn in over the edge of the support it
#: left, it stays clear of it
CARRY_RAISE = 0.05
#: m: an object resting on another object's top keeps its centre this far inside the top's edges
#: (at most a quarter of the top's size): the corners' patch forces then stand for a real overlap
SUPPORT_EDGE_MARGIN = 0.04
#: m: how far an object's nominal bottom may be from a top (or the floor) to be resting on it
SUPPORT_MATCH = 0.02

#: the carried-object weights (w_carry_*) are off here; S1's task file asks for w_carry_pose 500
#: (TrajectoryOptions.weights): with the fixed carry nominal S1's carry reached its iteration cap
#: without it and passed every check with it (docs/to.md, session 17)
#: ``hip_margin`` (rad): the hip roll kept this far inside ``hip_coupling``'s bound (0: on it). S1's
#: plans step onto the box on the bound (0.0-0.3 cm between the pelvis and hip-roll meshes); executed,
#: 0.05-0.1 rad of error jammed the two and the robot fell; with 0.08 in the step's subtask the plan
#: executes to task success in the box 2.0 kg world (docs/execution.md, session 50)
DEFAULT_WEIGHTS = {
    "w_post": 1.0, "w_xd": 0.05, "w_acc": 0.5, "w_force": 0.2, "w_force_rate": 20.0, "w_st_com": 20.0, "w_st_vel": 10.0,
    "w_kff": 5e2, "w_wk_base": 20.0, "w_upright": 20.0, "w_anchor": 10.0, "w_kfb_z": 100.0,
    "w_kfb_th": 10.0, "w_slack": 1e2, "w_self": 1e3, "w_swing": 2e3, "swing_clearance": 0.06,
    "w_pen": 1e4, "w_hom": 1e2, "w_obj_reg": 1.0, "w_obj_acc": 20.0, "w_carry_acc": 0.0, "w_carry_aacc": 0.0,
    "w_carry_pose": 0.0, "w_carry_offset": 0.0,
    "w_goal": 1e3,
    "mu_foot": 0.6, "mu_hand": 0.8, "mu_obj": 0.5, "self_margin": 0.0, "hip_margin": 0.0,
    "pair_prefilter": 0.25,
}


@dataclass
class Grid:
    t: np.ndarray  # knot times (K)
    phase: np.ndarray  # phase index per knot

    @property
    def K(self) -> int:
        return len(self.t)


def _lifts(phases, i: int) -> bool:
    """Whether an object is free (carried) in phase i and was not in the phase before it."""
    before = phases[i - 1].objects if i > 0 else {}
    return any(mo.mode == "free" and (o not in before or before[o].mode != "free") for o, mo in phases[i].objects.items())


def reaches(phases, i: int) -> bool:
    """Whether a hand makes a contact at the end of stance phase i that it does not have in it, the
    next phase being of the same subtask (segments are cut at subtask boundaries, so a segment's
    grid and the whole horizon's agree)."""
    if i + 1 >= len(phases) or phases[i].phase_type == WALKING or phases[i + 1].subtask_index != phases[i].subtask_index:
        return False
    now, nxt = phases[i].contacts, phases[i + 1].contacts
    return any(h in HANDS and h not in now for h in nxt)


def make_grid(prob: Problem) -> Grid:
    ts, ph = [], []
    for i, p in enumerate(prob.phases):
        dt = prob.options.dt_walking if p.phase_type == WALKING else prob.options.dt_stance
        if p.phase_type != WALKING and prob.options.dt_lift > 0 and _lifts(prob.phases, i):
            dt = prob.options.dt_lift
        elif prob.options.dt_reach > 0 and reaches(prob.phases, i):
            dt = prob.options.dt_reach
        n = max(1, int(math.ceil((p.end - p.start) / dt - 1e-9)))
        for k in range(n):
            ts.append(p.start + (p.end - p.start) * k / n)
            ph.append(i)
    ts.append(prob.phases[-1].end)
    ph.append(len(prob.phases) - 1)
    return Grid(np.array(ts), np.array(ph))


def obj_prims_world(o: SceneObject, p=None, rpy=None):
    """[(centre, R, half_extents)] of an object's primitives at pose (p, rpy) (default: its own)."""
    p = np.asarray(o.position, float) if p is None else np.asarray(p, float)
    R0 = rpy_to_rot(o.rpy() if rpy is None else np.asarray(rpy, float))
    out = []
    for pr in o.primitives:
        Rl = rpy_to_rot(np.array([0, 0, pr.yaw]))
        out.append((p + R0 @ np.asarray(pr.position, float), R0 @ Rl, pr.half_extents()))
    return out


def box_distances(points: np.ndarray, centre, R, half, radius) -> np.ndarray:
    """Signed distances of spheres (centres (n, 3), radius or radii) to a posed box."""
    q = np.abs((points - centre) @ R) - half
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0) - radius


def outside_top(p, centre, R, half) -> float:
    """How far (m) point ``p`` lies outside a posed box's top rectangle, in x or y (<= 0: over it)."""
    return float(np.max(np.abs((R.T @ (np.asarray(p, float)[:3] - centre))[:2]) - half[:2]))


def carried_points(o: SceneObject, r: float = CARRIED_POINT_RADIUS) -> np.ndarray:
    """(n, 4) point spheres (centre in the object frame, radius) standing for an object in its
    clearance rows: a 3 x 3 grid on the bottom and on the top face of each primitive's box, inset by
    ``r`` so each sphere touches the faces.  A primitive thinner than ``2 r`` (the basket's 1 cm
    floor and walls) gets spheres of its least half extent: at 1 cm they stood 5 mm below the
    basket's floor, so the first carried knot had to lift it 5 mm off the shelf at zero velocity,
    and S1's grab solves stalled at 1.27e-4 on the basket's integration rows (session 55).  A
    simplification: between the grid points an edge of another object can still cut into a face
    (1 cm at a table's edge under a box tilted 0.22 rad, docs/to.md session 28; the check samples
    more densely)."""
    out = []
    for pr in o.primitives:
        rp = min(r, float(np.min(pr.half_extents())))
        he = np.maximum(pr.half_extents() - rp, 0.0)
        Rz = rpy_to_rot(np.array([0.0, 0.0, pr.yaw]))
        for sz in (-1.0, 1.0):
            for sx in (-1.0, 0.0, 1.0):
                for sy in (-1.0, 0.0, 1.0):
                    out.append([*(np.asarray(pr.position, float) + Rz @ (he * [sx, sy, sz])), rp])
    return np.array(out).reshape(-1, 4)


def arm_body_pairs(model: G1Model, hand_body: bool = False) -> dict:
    """{(sphere i, sphere j): side} of Options.arm_body_self_pairs: per side the forearm and upper arm
    against the torso, the own upper thigh and hip front, and the hand, hand tip and wrist against
    the own hip front (those three are in ``hand_body``'s pairs already)."""
    idx = {s.name: i for i, s in enumerate(model.spheres)}
    out = {}
    for s in ("left", "right"):
        for arm in (f"{s}_forearm_0", f"{s}_upper_arm_0"):
            for other in ("torso_0", "torso_low_0", "torso_low_1", f"{s}_thigh_0", f"{s}_hip_front"):
                out[(idx[arm], idx[other])] = s
        if not hand_body:
            for arm in (f"{s}_hand", f"{s}_hand_tip", f"{s}_wrist"):
                out[(idx[arm], idx[f"{s}_hip_front"])] = s
    return out


def self_pairs(model: G1Model, hand_body: bool = False, arm_body: bool = False) -> tuple:
    """Sphere index pairs of the self-collision rows; ``hand_body``: Options.hand_body_self_pairs,
    ``arm_body``: Options.arm_body_self_pairs."""
    names = [s.name for s in model.spheres]
    idx = {n: i for i, n in enumerate(names)}
    pairs = []
    for s in ("left", "right"):
        pairs.append((idx[f"{s}_hand"], idx["torso_0"]))
        if hand_body:
            o = "right" if s == "left" else "left"
            for arm in (f"{s}_hand", f"{s}_hand_tip", f"{s}_wrist"):
                for other in (f"{o}_hip_pitch", f"{o}_hip_roll", f"{o}_hip_front", f"{o}_thigh_0",
                              "torso_low_0", "torso_low_1", f"{s}_hip_front", f"{s}_shin_0"):
                    pairs.append((idx[arm], idx[other]))
        for arm in (f"{s}_hand", f"{s}_hand_tip", f"{s}_wrist"):
            for other in ("pelvis", f"{s}_hip_pitch", f"{s}_hip_roll", f"{s}_thigh_0", f"{s}_thigh_1"):
                pairs.append((idx[arm], idx[other]))
        if arm_body:
            pairs += [p for p, side in arm_body_pairs(model, hand_body).items() if side == s]
        # elbow region against the knee in a squat: S1's lift had the forearm 50 mm into the shin
        for arm in (f"{s}_upper_arm_0", f"{s}_forearm_0"):
            for other in (f"{s}_thigh_1", f"{s}_shin_0", f"{s}_shin_1"):
                pairs.append((idx[arm], idx[other]))
        # thigh against the torso's lower front in deep squats (hip flexion plus a forward waist)
        for thigh in (f"{s}_hip_front", f"{s}_hip_roll"):
            for torso in ("torso_low_0", "torso_low_1"):
                pairs.append((idx[thigh], idx[torso]))
    legs = ("shin_0", "shin_1", "shin_2", "thigh_1")
    for a in legs:
        for b in legs:
            pairs.append((idx[f"left_{a}"], idx[f"right_{b}"]))
    pairs.append((idx["left_foot_0"], idx["right_foot_0"]))
    pairs.append((idx["left_foot_1"], idx["right_foot_1"]))
    return tuple(pairs)


#: m the sole centre keeps from a support surface's edges (sole half-width ~3 cm)
SOLE_EDGE_MARGIN = 0.06
#: m a forearm sphere may reach into an object its hand holds (Options.forearm_clear_of_held_object).
#: The TO's hand point (model.HAND_POINT) is on the wrist-yaw axis, but the rubber hand's inner face is
#: 4.5 cm from that axis (the sim's hand box: 1.2 cm offset, 3.3 cm half-thickness), so on the real
#: hand, held flat on a face, the forearm is 4.5 cm further out than the TO's model puts it, 4 cm
#: with the controller's 5 mm squeeze (lomanip_sim WbcGains.hand_squeeze), so at this depth the real
#: forearm just reaches the face. With 0 the TO could only satisfy the rows by turning the fingers
#: into the face (case_lift_box: 20 degrees)
HELD_OBJECT_FOREARM_DEPTH = 0.04
#: sine of the largest tilt of a swing sole (3 deg: heel/toe at most ~5 mm lower than the sole centre)
SWING_TILT = 0.05
#: least lateral distance (m) of the sole centres in the base's frame (the hips are 0.24 m apart):
#: keeps the legs from crossing, including between knots where the sphere pairs are not checked
FEET_MIN_LATERAL = 0.10
#: longitudinal force (N) a rolling object's wheel (support corner) may take: rolling resistance, the
#: same as the sim's trolley wheels (lomanip_sim S2TrolleyParams.wheel_rolling_resistance, tested).
#: With 0 (free rolling) no push was feasible: the hands push through a friction contact and cannot pull,
#: so nothing could stop the trolley at its goal, and every push converged with the trolley unmoved
WHEEL_ROLLING_RESISTANCE = 1.5
#: largest roll and pitch (rad) of a carried object: a carrying choice, like the gait rows. Without it
#: S1's plans tilted the box 0.3-0.7 rad while carrying it; a two-hand friction grasp under physics
#: then let it pivot about the axis between the hands and slide out (docs/execution.md, session 5)
CARRY_TILT = 0.25
#: speed (m/s, each axis) and turn rate (rad/s, each of roll/pitch/yaw rates) an object may reach
#: per knot over the first LIFT_OFF_KNOTS knots after it leaves its support (n times these at the
#: n-th). Why: at 0.2 s knots with an explicit Euler step, a 15 N imbalance of the hands' forces
#: moved S1's 2.5 kg box 0.27 m or yawed it 0.58 rad in its first free knot, in every passing plan,
#: and the executed friction grasp lost the box there (docs/execution.md, sessions 16-17)
LIFT_OFF_SPEED = 0.25
LIFT_OFF_TURN_RATE = 0.3
LIFT_OFF_KNOTS = 2
#: time (s) the nominal takes to stand up after the hands let go at the end of a task or segment
STAND_UP_TIME = 1.0


def _relative_to_base(x: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Object pose (p, rpy) in the frame of the base's floor-projected yaw: (p_rel, roll, pitch, dyaw)."""
    c, s = math.cos(x[5]), math.sin(x[5])
    d = pose[:3] - x[:3]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2], pose[3], pose[4], pose[5] - x[5]])


def _from_base(x: np.ndarray, rel: np.ndarray) -> np.ndarray:
    c, s = math.cos(x[5]), math.sin(x[5])
    return np.array([x[0] + c * rel[0] - s * rel[1], x[1] + s * rel[0] + c * rel[1], x[2] + rel[2],
                     rel[3], rel[4], rel[5] + x[5]])


class ProblemData:
    """All numeric arrays of one TO problem (bounds, parameters, warm start) + its structure."""

    def __init__(self, prob: Problem, model: G1Model, moving: list | None = None, pairs: list | None = None,
                 stand: np.ndarray | None = None, env_pairs: list | None = None):
        """``moving``/``pairs``/``env_pairs`` force the moving-object list, the robot's collision
        pairs and the carried objects' clearance pairs (subtask segments of a bigger problem share
        its window structure, so the window is built once); ``stand``
        is the standing posture the nominal returns to (default: the initial configuration)."""
        self.prob = prob
        self.model = model
        self.stand = np.asarray(prob.initial_configuration if stand is None else stand, float)
        opt = prob.options
        self.w = dict(DEFAULT_WEIGHTS)
        self.w.update(opt.weights or {})
        self.grid = make_grid(prob)
        self.moving = list(moving) if moving is not None else prob.moving_object_ids()
        self.midx = {oid: j for j, oid in enumerate(self.moving)}
        self.x_init = np.asarray(prob.initial_configuration, float)
        # objects a hand may come near on purpose: every moving one, and any a hand touches
        self._hand_touched = set(self.moving) | {c.object_id for ph in prob.phases for limb, c in ph.contacts.items()
                                                 if limb.endswith("_hand") and c is not None}
        self._object_timeline()
        self._warm_start_x()
        if pairs is None:
            self._choose_pairs()
        else:
            self.prims = [(o.id, pi) for o in prob.objects for pi in range(len(o.primitives))]
            self.pairs = list(pairs)
        self.env_pairs = list(env_pairs) if env_pairs is not None else self._choose_env_pairs()
        self.structure = Structure(len(self.moving), tuple(s for s, _ in self.pairs),
                                   self_pairs(model, opt.hand_body_self_pairs, opt.arm_body_self_pairs) if opt.self_collision else (),
                                   tuple(opt.inertial_torque_groups), opt.interval_momentum_tolerance > 0,
                                   opt.upper_body_acceleration_limit > 0, len(self.env_pairs),
                                   bool(opt.load_in_double_support_margin), float(opt.cop_margin_front),
                                   float(opt.hand_standoff), float(opt.cop_margin_side))
        self._arm_body_side = arm_body_pairs(model, opt.hand_body_self_pairs) if opt.arm_body_self_pairs else {}
        self.sole_force_points = sole_force_points(self.structure.cop_margin_front, self.structure.cop_margin_side)
        for oid in self.moving:  # an object set down in mid-air is refused here, before any solve
            for k in range(self.grid.K):
                self.support_under(k, oid)

    # ------------------------------------------------------------------ object nominal poses
    def _object_timeline(self):
        """Nominal pose of every moving object at every knot (initial pose, then goals)."""
        prob = self.prob
        K = self.grid.K
        self.obj_nom = {}
        self.carry_rel = {}  # object -> (K, 6) its nominal pose relative to the base while held (nan: not)
        self.support_poses = {}  # see use_solved_support_poses
        self._support_cache = {}  # (k, object) -> (top's object id, primitive, rest height) or None
        goals = {g.object_id: g for g in prob.placement_goals}
        for oid in self.moving:
            o = prob.object(oid)
            pose = np.concatenate([np.asarray(o.position, float), o.rpy()])
            traj = np.tile(pose, (K, 1))
            cur = pose.copy()
            for k, k1 in self._moving_intervals(oid):
                end = cur.copy()
                g = goals.get(oid)
                t_end = self.grid.t[min(k1, K - 1)]
                if g is not None and (g.time is None or g.time <= t_end + 1e-9):
                    end = np.concatenate([np.asarray(g.position, float), [0.0, 0.0, g.yaw]])
                for kk in range(k, min(k1 + 1, K)):
                    s = (kk - k) / max(1, (k1 - k))
                    traj[kk] = (1 - s) * cur + s * end
                cur = end
                traj[k1 + 1:] = cur
            self.obj_nom[oid] = traj

    def _pulled_in(self, rel: np.ndarray, tk: float, t_off: float, t_down: float) -> np.ndarray:
        """A carried object's pose relative to the base with its horizontal reach brought towards
        ``Options.carry_reach`` and raised by CARRY_RAISE, blended in after lift-off (t_off) and
        out before set-down (t_down)."""
        reach = float(np.hypot(rel[0], rel[1]))
        target = min(reach, self.prob.options.carry_reach)
        w = smoothstep((tk - t_off) / CARRY_REACH_BLEND) * smoothstep((t_down - tk) / CARRY_REACH_BLEND)
        out = rel.copy()
        if reach > 1e-9:
            out[0:2] *= (1.0 - w) + w * target / reach
        out[2] += w * CARRY_RAISE
        return out

    def _moving_intervals(self, oid: str) -> list:
        """(first knot, first knot after) of each stretch in which ``oid`` moves (it is in the
        phases' objects); the knot after is where it comes to rest (K if it never does)."""
        K, out, k = self.grid.K, [], 0
        while k < K:
            if oid in self.prob.phases[self.grid.phase[k]].objects:
                k1 = k
                while k1 < K and oid in self.prob.phases[self.grid.phase[k1]].objects:
                    k1 += 1
                out.append((k, k1))
                k = k1 + 1
            else:
                k += 1
        return out

    def _objects_follow_base(self, X: np.ndarray) -> None:
        """A held object moves with the robot's nominal base, not on its own clock.

        Why: the linear object nominal of :meth:`_object_timeline` and the base nominal (paced by
        the walking phases along a route) disagreed by up to 0.5 m during S1's carry; the warm
        start's IK, pulled by the hands to the box and by the feet to the footholds, then swung the
        base yaw by 1.5 rad and its knots jumped (momentum rows violated by 3.4 at the first
        iterate).  Here, over each stretch in which a hand holds the object, its pose relative to
        the base (position and yaw) blends from the one at the stretch's start to the one at its
        end, in time; a supported or rolling object keeps its height and tilt.  Objects attached
        to it follow it.  Rest poses (before and after) are unchanged."""
        t = self.grid.t
        for oid in self.moving:
            traj = self.obj_nom[oid]
            for k0, k_rest in self._moving_intervals(oid):
                k1 = min(k_rest, self.grid.K - 1)
                held = any(c.object_id == oid for k in range(k0, k1 + 1)
                           for h in HANDS if (c := self.contact(k, h)) is not None)
                if not held or k1 <= k0:
                    continue
                if self._pushed_stretch(X, oid, k0, k1):
                    continue
                # a carry that ends on a support inside the stretch (S1's box set down at its goal)
                # blends to the set-down knot, and the object rests at its placed pose after it.
                # Why: blended to the stretch's end, where the nominal has stood up again, S1's box
                # went 0.3 m under the floor before its placement and the warm start's IK, pulled
                # there by the hands, rolled the base 0.6 rad (session 17)
                free = [k for k in range(k0, k1 + 1) if self.obj_mode(k, oid) == "free"]
                if free and free[-1] + 1 < k1 and all(self.obj_mode(k, oid) in ("supported", "fixed")
                                                      for k in range(free[-1] + 1, k1 + 1)):
                    k_set = free[-1] + 1
                    traj[k_set:k1 + 1] = traj[k1]
                    k1 = k_set
                rel0 = _relative_to_base(X[k0], traj[k0])
                rel1 = _relative_to_base(X[k1], traj[k1])
                k_end = k1
                if k_rest >= self.grid.K and not self._goal_in_horizon(oid):
                    # still carried at the horizon's end (a segment cut at a rest point): it rides
                    # with the base to the last knot instead of going back to where it started
                    rel1, k_end = rel0.copy(), k1 + 1
                rel1[5] = rel0[5] + math.remainder(rel1[5] - rel0[5], 2 * math.pi)
                free_t = [t[k] for k in free]
                for k in range(k0 + 1, k_end):
                    s = (t[k] - t[k0]) / (t[k1] - t[k0])
                    rel = (1 - s) * rel0 + s * rel1
                    if self.prob.options.carry_reach > 0 and self.obj_mode(k, oid) == "free":
                        rel = self._pulled_in(rel, t[k], free_t[0], free_t[-1])
                    pose = _from_base(X[k], rel)
                    self.carry_rel.setdefault(oid, np.full((self.grid.K, 6), np.nan))[k] = rel
                    if self.obj_mode(k, oid) in ("supported", "rolling"):
                        pose[[2, 3, 4]] = traj[k, [2, 3, 4]]
                    traj[k] = pose
            for other in self.moving:  # objects riding on it
                for k in range(self.grid.K):
                    mo = self.prob.phases[self.grid.phase[k]].objects.get(other)
                    if mo is not None and mo.mode == "attached" and mo.attached_to == oid:
                        off = self._attach_offset(k, other, oid)
                        pc = traj[k]
                        pose = self.obj_nom[other][k].copy()
                        pose[:3] = pc[:3] + rpy_to_rot(pc[3:]) @ off[:3]
                        pose[5] = pc[5] + off[3]
                        self.obj_nom[other][k] = pose

    def _goal_in_horizon(self, oid: str) -> bool:
        t_end = self.grid.t[-1] + 1e-9
        return any(g.object_id == oid and (g.time is None or g.time <= t_end) for g in self.prob.placement_goals)

    def _pushed_stretch(self, X: np.ndarray, oid: str, k0: int, k1: int) -> bool:
        """A held object that rolls or slides on its support towards its goal while the base
        nominal stays put (the keyframe is the grasp, the push comes after it): the base walks with
        the object instead, to the end of the subtask. Returns whether it did.

        Why: the object then moved 0.5 m in the nominal while the base stood at the handle, and
        every S2 and demo push converged with the trolley never moving (hands at 0 N)."""
        modes = {self.obj_mode(k, oid) for k in range(k0 + 1, k1 + 1)}
        if not modes <= {"rolling", "supported"}:
            return False
        traj = self.obj_nom[oid]
        d_obj = traj[k1, :2] - traj[k0, :2]
        if np.linalg.norm(d_obj) < 0.05 or np.linalg.norm(X[k1, :2] - X[k0, :2]) > 0.5 * np.linalg.norm(d_obj):
            return False
        sub = self.prob.phases[self.grid.phase[k0]].subtask_index
        for k in range(k0 + 1, self.grid.K):
            if self.prob.phases[self.grid.phase[k]].subtask_index != sub:
                break
            X[k, :2] += traj[min(k, k1), :2] - traj[k0, :2]
        return True

    def obj_mode(self, k: int, oid: str) -> str:
        ph = self.prob.phases[self.grid.phase[k]]
        mo = ph.objects.get(oid)
        if mo is None:
            return "fixed"
        if mo.mode == "free" and self._lift_start(k, oid, mo):
            return "supported"
        return mo.mode

    def resting_under_hands(self, k: int, oid: str) -> bool:
        """Whether ``oid`` rests untouched by the plan's motions ("fixed") at knot k while a hand
        touches it, and ``Options.resting_object_dynamics`` gives it its support's forces and its
        dynamics there (at rest), instead of holding it as an immovable support."""
        if not self.prob.options.resting_object_dynamics or self.obj_mode(k, oid) != "fixed":
            return False
        return any((c := self.contact(k, h)) is not None and c.object_id == oid for h in HANDS)

    def _knots_after_lift_off(self, k: int, oid: str) -> int:
        """n (1..LIFT_OFF_KNOTS) if knot ``k`` is the n-th free knot after the one at which ``oid``
        left its support (that one is at rest), else 0. Resting untouched ("fixed", S2's box on the
        table) counts as on a support: before session 35 only "supported" and "rolling" did, so S2's
        lift never had the gentle start."""
        for n in range(1, LIFT_OFF_KNOTS + 1):
            if k - n - 1 < 0 or any(self.obj_mode(k - i, oid) != "free" for i in range(n + 1)):
                return 0
            if self.obj_mode(k - n - 1, oid) in ("supported", "rolling", "fixed"):
                return n
        return 0

    def _lift_start(self, k: int, oid: str, mo) -> bool:
        """Whether knot ``k`` is the first of a lift: the object is free from here but was resting.

        Why: forces act over [t_k, t_k+1], so an object free at its first knot had to be carried by
        the hands alone from a posture chosen without its load (a segment's fixed first state, S1's
        squat at the box): the waist could not, and the plans let the box fall 14 cm into the floor.
        At that knot it still stands on its support (which may carry it) while the hands load up."""
        phase = self.grid.phase[k]
        if k > 0 and self.grid.phase[k - 1] == phase:
            return False
        if any(oid in ph.objects for ph in self.prob.phases[:phase]):
            return False   # it moved before: only a first lift from where the scene has it
        sup = mo.support
        if sup != FLOOR and sup not in {o.id for o in self.prob.objects}:
            return False   # no named support to stand on
        o = self.prob.object(oid)
        rpy = o.rpy()
        return (abs(float(o.position[2]) - (self._support_top(sup) - o.bottom_z())) < 1e-3
                and abs(rpy[0]) < 1e-3 and abs(rpy[1]) < 1e-3)

    def _support_top(self, support: str) -> float:
        """World height of the top of ``support`` (the floor: 0) where the scene has it."""
        if support == FLOOR:
            return 0.0
        s = self.prob.object(support)
        return float(np.asarray(s.position)[2] + s.top_z())

    def contact(self, k: int, limb: str):
        return self.prob.phases[self.grid.phase[k]].contacts.get(limb)

    def _torque_margins(self) -> np.ndarray:
        """Bound of each torque row as a fraction of the joint's limit, in the window's row order."""
        n = sum(len(js) for js, _ in self.model.torque_row_joints.values())
        return np.full(n, self.prob.options.torque_margin)

    def rest_height(self, oid: str, support: str) -> float:
        """World height of ``oid``'s origin when it rests on ``support``."""
        return self._support_top(support) - self.prob.object(oid).bottom_z()

    def support_under(self, k: int, oid: str):
        """(object id, primitive index) of the top ``oid`` rests on at knot ``k``, or None (on the
        floor, or not resting).  Resting: supported or rolling on a named object, or the first
        knot it is fixed after a motion (set down: the top under its nominal pose then)."""
        key = (k, oid)
        if key not in self._support_cache:
            self._support_cache[key] = self._find_support(k, oid)
        hit = self._support_cache[key]
        return None if hit is None else hit[:2]

    def _find_support(self, k: int, oid: str):
        mode = self.obj_mode(k, oid)
        prev = self.obj_mode(k - 1, oid) if k > 0 else "fixed"
        ph = self.prob.phases[self.grid.phase[k]]
        named = None
        if mode in ("supported", "rolling"):
            named = ph.objects[oid].support
            if named == FLOOR:
                return None
        elif not (mode == "fixed" and prev != "fixed"):
            return None
        o = self.prob.object(oid)
        p = self.obj_nom[oid][k]
        bottom = p[2] + o.bottom_z() if named is None else self._support_top(named)
        if named is None and bottom <= SUPPORT_MATCH:
            return None  # set down on the floor: unbounded
        best = None
        for s in self.prob.objects:
            if s.id == oid or (named is not None and s.id != named):
                continue
            sp = self.obj_nom[s.id][k] if s.id in self.obj_nom else None
            prims = obj_prims_world(s, *((sp[:3], sp[3:]) if sp is not None else ()))
            for pi, (c, R, half) in enumerate(prims):
                if abs(c[2] + half[2] - bottom) > SUPPORT_MATCH or abs(R[2, 2] - 1) > 1e-6:
                    continue
                out = outside_top(p, c, R, half)
                if best is None or out < best[0]:
                    best = (out, s.id, pi, c[2] + half[2])
        if best is None or best[0] > SUPPORT_MATCH:
            raise ProblemError(INVALID_REQUEST, f"'{oid}' is set down at t={self.grid.t[k]:.2f} s with its bottom "
                               f"{bottom:.2f} m up and no object's top under it", "phases")
        return best[1], best[2], best[3] - o.bottom_z()

    def _support_bounds(self, k: int, oid: str) -> np.ndarray:
        """Half extents (x, y) of the support top less SUPPORT_EDGE_MARGIN; inf where unbounded."""
        sup = self.support_under(k, oid)
        if sup is None:
            return np.full(2, INF)
        half = self.prob.object(sup[0]).primitives[sup[1]].half_extents()[:2]
        return half - np.minimum(SUPPORT_EDGE_MARGIN, 0.25 * half)

    def _placement_tolerance(self, k: int, oid: str) -> float:
        """Options.placement_tolerance at the knot of each of ``oid``'s placement goals (inf
        elsewhere, or when the option is 0: the goal is then a cost only)."""
        tol = self.prob.options.placement_tolerance
        if tol <= 0:
            return INF
        return tol if any(g.object_id == oid and k == self.goal_knot(g) for g in self.prob.placement_goals) else INF

    def goal_knot(self, g) -> int:
        """Knot of a placement goal's time (the end when it has none)."""
        return int(np.argmin(np.abs(self.grid.t - (self.prob.duration if g.time is None else g.time))))

    def _touched(self, k: int, oid: str) -> bool:
        """Whether a limb or another object loads ``oid`` at knot ``k``."""
        ph = self.prob.phases[self.grid.phase[k]]
        if any(c.object_id == oid for c in ph.contacts.values()):
            return True
        return any(mo.support == oid or mo.attached_to == oid for o, mo in ph.objects.items() if o != oid)

    def _left_alone(self, k: int, oid: str) -> bool:
        """An object resting on its support that nothing has touched since the knot before is at
        rest at ``k`` (its velocity over [t_k-1, t_k] is zero).

        Why: the support's friction is a linearised cone with no dissipation row, so on its own it
        could drive an object. S1's placed box slid 0.35 m along the floor after the hands let go
        (no force on it but the floor's). Named simplification: an object let go while sliding
        stops within one knot."""
        if k == 0 or self.obj_mode(k, oid) != "supported" or self.obj_mode(k - 1, oid) != "supported":
            return False
        return not (self._touched(k - 1, oid) or self._touched(k, oid))

    # ------------------------------------------------------------------ warm start / references
    def _warm_start_x(self):
        prob, K = self.prob, self.grid.K
        opt = prob.options
        kf_by_sub = {}
        for kf in prob.keyframes:
            kf_by_sub.setdefault(kf.subtask_index, kf)
        self.kf_knots = {}
        for kf in prob.keyframes:
            t = prob.keyframe_time(kf)
            if t > self.grid.t[-1] + 1e-6:
                continue  # after a segment cut at a rest point: anchors the nominal only
            self.kf_knots[int(np.argmin(np.abs(self.grid.t - t)))] = kf
        X = np.tile(self.x_init, (K, 1))
        if opt.use_keyframe_warm_start and prob.keyframes:
            X = self._keyframe_nominal()
            X[0] = self.x_init
            self._objects_follow_base(X)
            if opt.stepping_warm_start:
                from .warm_start import stepping_guess

                X = stepping_guess(self, X)
        self.x_guess = X

    def _sole_height(self, x: np.ndarray) -> float:
        return float(min(self.model.numeric(x)["limbs"][f][0][2] for f in FEET))

    def _keyframe_nominal(self, blend_time: float = 1.0) -> np.ndarray:
        """Nominal state of every knot from the keyframes (paper IV-B: keyframes initialise the
        shooting nodes of their subtask).  Named variant: between consecutive anchors (initial state,
        keyframes at their times) the base moves along its route, paced by the walking phases; the
        posture (joints, base height above the support, roll/pitch) is the anchor's while the hands
        hold what they hold at the keyframe with the feet planted (:meth:`_hold_window`), and
        blends to the standing posture over ``blend_time`` outside it (smoothstep: no velocity
        jumps), so a long carry is initialised walking upright rather than squatting.  After the
        last keyframe its state is held while a hand still touches something, then the robot
        stands up over ``STAND_UP_TIME`` (a segment that ends after placing the box ends standing
        or on its way up: the next one starts from there)."""
        prob, t = self.prob, self.grid.t
        anchors = [(0.0, self.x_init.copy())]
        holds = [(0.0, 0.0)]
        for kf in sorted(prob.keyframes, key=prob.keyframe_time):
            anchors.append((prob.keyframe_time(kf), kf.x()))
            holds.append(self._hold_window(prob.keyframe_time(kf)))
        h = [self._sole_height(x) for _, x in anchors]
        stand = self.stand.copy()
        h_stand = self._sole_height(stand)
        X = np.tile(anchors[-1][1], (len(t), 1))
        self.routes = [self._base_route(ta, xa, xb) for (ta, xa), (_, xb) in zip(anchors, anchors[1:])]
        blends: dict[int, tuple] = {}   # knot -> (anchor interval, wa, wb, ws)
        for k, tk in enumerate(t):
            for i in range(len(anchors) - 1):
                (ta, xa), (tb, xb) = anchors[i], anchors[i + 1]
                if not ta - 1e-9 <= tk <= tb + 1e-9:
                    continue
                s = self._walk_fraction(ta, tk, tb)
                wa = 1.0 - smoothstep((tk - holds[i][1]) / blend_time)
                wb = 1.0 - smoothstep((holds[i + 1][0] - tk) / blend_time)
                if wa + wb > 1.0:
                    wa, wb = wa / (wa + wb), wb / (wa + wb)
                ws = 1.0 - wa - wb
                x = wa * xa + wb * xb + ws * stand
                blends[k] = (i, wa, wb, ws)
                x[[0, 1]] = point_along(self.routes[i], s)
                x[5] = walking_heading(self.routes[i], s, xa[5], xb[5])  # a long sideways walk turns
                sup = (1 - s) * h[i] + s * h[i + 1]
                x[2] = wa * xa[2] + wb * xb[2] + ws * (stand[2] - h_stand + sup)
                X[k] = x
                break
        self._follow_the_feet(X, anchors, blends, stand)
        ta, xa = anchors[-1]
        if ta < t[-1]:
            hands_free = [all(self.contact(k, hnd) is None for hnd in HANDS) for k in range(len(t))]
            k_free = len(t)
            while k_free > 0 and hands_free[k_free - 1] and t[k_free - 1] >= ta - 1e-9:
                k_free -= 1
            for k in range(k_free, len(t)):
                ws = smoothstep((t[k] - t[k_free]) / STAND_UP_TIME)
                x = (1 - ws) * xa + ws * stand
                x[[0, 1, 5]] = xa[[0, 1, 5]]
                x[2] = (1 - ws) * xa[2] + ws * (stand[2] - h_stand + h[-1])
                X[k] = x
        return X

    def _feet_at(self, t: float):
        """(mid-feet xy, mean sole heading) at time ``t`` from the schedule's footholds, a swing
        foot sliding from its last foothold to its next over the step; None where a foothold has
        no position or heading (the hand-written fixtures) or ``t`` is outside the schedule."""
        phases = self.prob.phases
        if not phases or t < phases[0].start - 1e-9 or t > phases[-1].end + 1e-9:
            return None
        p = next((i for i, ph in enumerate(phases) if ph.start - 1e-9 <= t < ph.end - 1e-9), len(phases) - 1)
        ph = phases[p]

        def held(c):
            return c is not None and c.position is not None and c.heading is not None

        pts, hds = [], []
        for f in FEET:
            c = ph.contacts.get(f)
            if held(c):
                pts.append(np.asarray(c.position, float)[:2])
                hds.append(float(c.heading))
                continue
            if ph.phase_type != WALKING or p == 0 or p + 1 >= len(phases):
                return None
            a, b = phases[p - 1].contacts.get(f), phases[p + 1].contacts.get(f)
            if not (held(a) and held(b)):
                return None
            u = (t - ph.start) / max(ph.end - ph.start, 1e-9)
            pts.append((1 - u) * np.asarray(a.position, float)[:2] + u * np.asarray(b.position, float)[:2])
            hds.append(a.heading + u * math.remainder(b.heading - a.heading, 2 * math.pi))
        return 0.5 * (pts[0] + pts[1]), hds[0] + 0.5 * math.remainder(hds[1] - hds[0], 2 * math.pi)

    def _follow_the_feet(self, X: np.ndarray, anchors: list, blends: dict, stand: np.ndarray) -> None:
        """Base xy and heading of the knots between two anchors from the schedule's footholds where
        every foothold there has a heading (the planner's footsteps; the fixtures have none): the
        mid-feet point plus the base's offset from it, and the feet's mean heading plus the base's
        heading offset, the anchors' and the standing posture's offsets blended as the posture is.

        Why: the route nominal paces the base by walking time and turns it over 40 % of the route,
        while the footsteps turn in their first small steps: the walking cost (``w_wk_base``) held
        S1's carrying base 0.5 rad behind its feet, which stood 0.38 m apart, and the executed robot
        fell (session 53). Off the route it also kept an upright robot 18 cm behind its feet where
        the squatting keyframe's pelvis was."""
        t = self.grid.t

        def frame_offset(x, feet):
            mid, h = feet
            c, s = math.cos(h), math.sin(h)
            d = np.asarray(x[:2], float) - mid
            return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]), math.remainder(float(x[5]) - h, 2 * math.pi)

        limbs = self.model.numeric(stand)["limbs"]
        feet_stand = (0.5 * (np.asarray(limbs[FEET[0]][0], float)[:2] + np.asarray(limbs[FEET[1]][0], float)[:2]),
                      float(stand[5]))
        d_stand, _ = frame_offset(stand, feet_stand)
        for i in range(len(anchors) - 1):
            knots = [k for k, b in blends.items() if b[0] == i]
            (ta, xa), (tb, xb) = anchors[i], anchors[i + 1]
            fa, fb = self._feet_at(ta), self._feet_at(tb)
            feet = {k: self._feet_at(float(t[k])) for k in knots}
            if fa is None or fb is None or any(f is None for f in feet.values()):
                continue
            (da, ha), (db, hb) = frame_offset(xa, fa), frame_offset(xb, fb)
            for k in knots:
                _, wa, wb, ws = blends[k]
                mid, h = feet[k]
                d = wa * da + wb * db + ws * d_stand
                c, s = math.cos(h), math.sin(h)
                X[k, 0:2] = mid + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])
                yaw = h + wa * ha + wb * hb
                X[k, 5] = X[k, 5] + math.remainder(yaw - X[k, 5], 2 * math.pi)

    def _hold_window(self, t_kf: float) -> tuple:
        """(start, end) times around a keyframe in which the robot is in the keyframe's posture:
        the knots next to it with the same hand contacts (at least one) and both feet planted.

        Why: the hands reach the keyframe's contact points only in its posture; when the posture
        only blended in from the standing one at the keyframe (S1's pick: hands on the box 0.4 s
        before it), the warm start's IK dropped the knees by 1.1 rad in one knot to get there."""
        t = self.grid.t
        if t_kf > t[-1] + 1e-6:
            return t_kf, t_kf  # a keyframe after the horizon (a segment cut at a rest point)
        k_kf = int(np.argmin(np.abs(t - t_kf)))

        def grip(k):
            return tuple((h, c.object_id) for h in HANDS if (c := self.contact(k, h)) is not None)

        def same(k):
            return (grip(k) == grip(k_kf) and all(self.contact(k, f) is not None for f in FEET))

        if not grip(k_kf) or not same(k_kf):
            return t_kf, t_kf
        held = {oid for _, oid in grip(k_kf)}

        def carried(k):
            return any(oid in self.midx and self.obj_mode(k, oid) == "free" for oid in held)

        k0 = k1 = k_kf
        while k0 > 0 and same(k0 - 1):
            k0 -= 1
        # after the keyframe (a grasp), the hold ends where the held object is lifted: the nominal
        # stands up in the lift's double stance, not in the first step after it (S1: the squat
        # was held through the 0.8 s lift and the box rose 0.2 -> 0.66 m on one foot, 3.8-4.5 s)
        while k1 < len(t) - 1 and same(k1 + 1) and not carried(k1 + 1):
            k1 += 1
        return min(t[k0], t_kf), max(t[k1], t_kf)

    def _walking_time(self, t: float) -> float:
        """Time spent in walking phases up to ``t``."""
        return sum(max(0.0, min(t, ph.end) - ph.start) for ph in self.prob.phases if ph.phase_type == WALKING)

    def _walk_fraction(self, ta: float, t: float, tb: float) -> float:
        """How far along its route the base is at ``t`` between anchors at ta and tb: the share of
        the walking time between them already walked (the base moves while stepping, not while
        standing to grasp), or the share of time if there is no walking in between."""
        total = self._walking_time(tb) - self._walking_time(ta)
        if total < 1e-6:
            return (t - ta) / max(tb - ta, 1e-9)
        return min(1.0, max(0.0, (self._walking_time(t) - self._walking_time(ta)) / total))

    def _base_route(self, ta: float, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
        """Floor route of the base from anchor a to anchor b round the objects the robot neither
        touches nor moves at ta (:mod:`lomanip_to.route`), at their nominal poses at ta.  An object
        the robot walks up to (the trolley's handle) is an obstacle on the way; the route ends
        next to it, since an end point near an obstacle shrinks that obstacle's clearance."""
        k0 = int(np.argmin(np.abs(self.grid.t - ta)))
        ph = self.prob.phases[self.grid.phase[k0]]
        touched = {c.object_id for c in ph.contacts.values()} | set(ph.objects)
        obstacles = []
        for o in self.prob.objects:
            if o.id in touched or not o.primitives:
                continue
            pose = self.obj_nom[o.id][k0] if o.id in self.obj_nom else np.concatenate([np.asarray(o.position, float), o.rpy()])
            obstacles.append(footprint_of(o, pose[:3], pose[3:]))
        return shortest_route(xa[:2], xb[:2], obstacles)

    def _choose_pairs(self):
        """Minimal collision set: sphere groups from the options x object primitives whose
        distance along the warm-start trajectory comes below ``pair_prefilter`` (heuristic)."""
        prob, m = self.prob, self.model
        groups = set(prob.options.collision_groups)
        sph_idx = [i for i, s in enumerate(m.spheres) if s.group in groups]
        # sphere centres along the warm start at every knot (and the initial configuration). Every
        # 5th knot (S1's K // 25) missed the left hand's pass 0.21 m from a shelf board in the step
        # onto the box; the solve took the hand 48 mm into it with no pair to stop it (session 43)
        cs = []
        for x in list(self.x_guess) + [self.x_init]:
            cs.append(m.numeric(x)["spheres"])
        cs = np.array(cs)  # T x S x 3
        self.prims = []  # (object id, primitive index)
        for o in prob.objects:
            for pi in range(len(o.primitives)):
                self.prims.append((o.id, pi))
        pairs = []
        thr = self.w["pair_prefilter"]
        for (oid, pi) in self.prims:
            o = prob.object(oid)
            if oid in self.moving:
                poses = self.obj_nom[oid][:: max(1, self.grid.K // 25)]
            else:
                poses = [np.concatenate([np.asarray(o.position, float), o.rpy()])]
            for s in sph_idx:
                r = m.spheres[s].radius
                dmin = INF
                for pose in poses:
                    prim = obj_prims_world(o, pose[:3], pose[3:])[pi]
                    dmin = min(dmin, float(box_distances(cs[:, s, :], *prim, r).min()))
                if dmin < thr:
                    pairs.append((s, (oid, pi)))
        self.pairs = pairs

    def carried_free_knots(self, oid: str) -> list:
        """Knots at which ``oid`` is carried free (off every support)."""
        return [k for k in range(self.grid.K) if self.obj_mode(k, oid) == "free"]

    def _choose_env_pairs(self) -> list:
        """[(object id, point sphere (x, y, z, r) in its frame, (other object id, primitive index))]:
        the point spheres of each object carried free (:func:`carried_points`) x the primitives of
        every other object that come within ``pair_prefilter`` of them along the object nominal
        (heuristic, as :meth:`_choose_pairs`)."""
        thr = self.w["pair_prefilter"]
        out = []
        for oid in self.moving:
            free = self.carried_free_knots(oid)
            if not free:
                continue
            o = self.prob.object(oid)
            pts = carried_points(o)
            others = [other for other in self.prob.objects if other.id != oid]
            dmin = {(other.id, pi): np.full(len(pts), INF) for other in others for pi in range(len(other.primitives))}
            for k in free[:: max(1, len(free) // 25)] + [free[-1]]:
                pose = self.obj_nom[oid][k]
                cw = pose[:3] + pts[:, :3] @ rpy_to_rot(pose[3:]).T
                for other in others:
                    opose = self.obj_nom.get(other.id)
                    prims = (obj_prims_world(other, opose[k][:3], opose[k][3:]) if opose is not None
                             else obj_prims_world(other))
                    for pi, prim in enumerate(prims):
                        dmin[other.id, pi] = np.minimum(dmin[other.id, pi], box_distances(cw, *prim, pts[:, 3]))
            for other in others:
                for pi in range(len(other.primitives)):
                    out.extend((oid, tuple(float(v) for v in pts[n]), (other.id, pi))
                               for n in np.flatnonzero(dmin[other.id, pi] < thr))
        return out

    def _env_enabled(self, k: int, oid: str) -> bool:
        return self.obj_mode(k, oid) == "free"

    def _env_params(self, i: int, col, P) -> None:
        oid, pt, (po, pi) = self.env_pairs[i]
        osel = np.zeros(len(self.moving))
        osel[self.midx[oid]] = 1.0
        col[P[f"e{i}_obj"]] = osel
        col[P[f"e{i}_pt"]] = pt
        col[P[f"e{i}_half"]] = self._primitive_params(f"e{i}", po, pi, col, P)

    # ------------------------------------------------------------------ arrays
    def _initial_tilt(self, foot: str) -> np.ndarray:
        """Sole tilt rows (R[0,2], R[1,2]) of the fixed initial configuration.  Knot 0's x is fixed
        (except the base height, which does not tilt a sole), so these rows are constants there: a
        start measured in the sim with a sole tilted by 3e-4 made them infeasible and ipopt iterated
        to its acceptable level (push_trolley: final stage ~200 extra iterations at viol 3.04e-4).
        Their bounds at knot 0 are widened to include the start; every later knot is unchanged."""
        if not hasattr(self, "_tilt0"):
            limbs = self.model.numeric(self.x_init)["limbs"]
            self._tilt0 = {f: np.array([limbs[f][1][0, 2], limbs[f][1][1, 2]]) for f in FEET}
        return self._tilt0[foot]

    def fill(self, win: Window, expo: float, hard: bool, penalty: bool, homotopy: "bool | str"):
        """Bounds (lbw, ubw: n_w x (K+1)), row bounds (lbg, ubg: n_g x K), params P (n_p x K), W0."""
        prob, m, w = self.prob, self.model, self.w
        opt = prob.options
        K = self.grid.K
        N = K - 1
        W, P, Gl = win.W, win.P, win.G
        lbw = np.full((W.n, K + 1), -INF)
        ubw = np.full((W.n, K + 1), INF)
        lbg = np.zeros((Gl.n, K))
        ubg = np.zeros((Gl.n, K))
        Pm = np.zeros((P.n, K))
        t = self.grid.t

        def setb(name, k, lo, hi):
            lbw[W[name], k] = lo
            ubw[W[name], k] = hi

        def rows(name, k, lo, hi):
            lbg[Gl[name], k] = lo
            ubg[Gl[name], k] = hi

        # ---------------- variable bounds
        q_lo, q_hi = m.gait_q_bounds(opt.waist_yaw_range, self.x_init[6:])
        knees = [m.joint_names.index(f"{s}_knee_joint") for s in ("left", "right")]
        bend_from = prob.phases[0].end if prob.phases else INF  # the start is measured (straight knees)
        for k in range(K):
            xl = np.full(35, -INF)
            xu = np.full(35, INF)
            xl[2], xu[2] = 0.2, 1.6
            xl[3:5], xu[3:5] = -0.9, 0.9
            xl[6:], xu[6:] = q_lo, q_hi
            if opt.min_knee_bend > 0 and t[k] >= bend_from - 1e-9:
                for j in knees:
                    xl[6 + j] = max(xl[6 + j], opt.min_knee_bend)
            setb("x", k, xl, xu)
            vmax = np.concatenate([np.full(6, 4.0), m.vel_max])
            if opt.upper_body_speed_limit > 0:
                vmax[UPPER_BODY_XD] = np.minimum(vmax[UPPER_BODY_XD], opt.upper_body_speed_limit)
            setb("xd", k, -vmax, vmax)
            setb("comd", k, -3, 3)
            setb("kk", k, -2, 2)
            for f in FEET:
                c = self.contact(k, f)
                lo = np.zeros(12)
                hi = np.zeros(12)
                if c is not None:
                    lo = np.tile([-2.0, -2.0, 0.0], 4)
                    hi = np.tile([2.0, 2.0, 2.0], 4)
                setb(f"u_{f}", k, lo, hi)
            for h in HANDS:
                c = self.contact(k, h)
                a = 1.0 if c is not None else 0.0
                setb(f"u_{h}", k, -a, a)
                setb(f"tau_{h}", k, -0.1 * a, 0.1 * a)  # patch moment, m g x 1 m units
            for oid, j in self.midx.items():
                mode = self.obj_mode(k, oid)
                prev = self.obj_mode(k - 1, oid) if k > 0 else "fixed"
                # lift-off: the first free knot after resting on a support has the object still at
                # rest, so the support's last force (which acts over [t_k-1, t_k]) only holds it and
                # the hands alone accelerate it from there. Without this the floor's force at the
                # last supported knot launched S1's box 14 cm up while the hands pushed it down.
                lift_off = mode == "free" and prev in ("supported", "rolling")
                n_lift = self._knots_after_lift_off(k, oid)
                if mode == "fixed" or prev == "fixed" or k == 0 or lift_off or self._left_alone(k, oid):
                    setb(f"o{j}_vel", k, 0, 0)
                elif n_lift:  # the knots right after a lift-off: a gentle start (LIFT_OFF_SPEED)
                    lim = n_lift * np.array([LIFT_OFF_SPEED] * 3 + [LIFT_OFF_TURN_RATE] * 3)
                    lo, hi = -lim, lim.copy()
                    v_up = float(opt.lift_off_vertical)
                    if v_up > 0.0:  # straight up off the support first (Options.lift_off_vertical)
                        lo[:2], hi[:2] = -v_up, v_up
                        lo[2] = min(v_up, hi[2])
                    setb(f"o{j}_vel", k, lo, hi)
                else:
                    setb(f"o{j}_vel", k, -3, 3)
                if mode in ("supported", "rolling") or self.resting_under_hands(k, oid):
                    setb(f"o{j}_us", k, np.tile([-1, -1, 0.0], 4), np.tile([1, 1, 1.0], 4))
                else:
                    setb(f"o{j}_us", k, 0, 0)
                if k == 0:
                    o = prob.object(oid)
                    pose0 = np.concatenate([np.asarray(o.position, float), o.rpy()])
                    setb(f"o{j}_pose", k, pose0, pose0)
                elif mode == "free":  # carried: roll and pitch within CARRY_TILT
                    setb(f"o{j}_pose", k, [-INF, -INF, -INF, -CARRY_TILT, -CARRY_TILT, -INF],
                         [INF, INF, INF, CARRY_TILT, CARRY_TILT, INF])
            # a slack whose pair is off at this knot has no row and no cost: left free, the barrier
            # alone pushed it up without end (S1's carry: 4.3 after 700 iterations), so pin it
            setb("slack", k, 0, np.array([INF if homotopy is True and self._surrogate_on(k, s, oid) else 0.0
                                          for s, (oid, _) in self.pairs]))
        # start and end at rest: only xd is bounded (bounding the momenta too would leave the CMM
        # rows of these knots with an all-zero Jacobian -> degenerate, slow ipopt convergence)
        setb("xd", 0, 0, 0)
        # the robot starts where it is: initial configuration fixed except the base height
        # (anchored by a cost, so a slightly inconsistent start height stays feasible)
        x0l, x0u = self.x_init.copy(), self.x_init.copy()
        x0l[2], x0u[2] = 0.2, 1.6
        setb("x", 0, x0l, x0u)
        setb("xd", N, 0, 0)
        # objects end at rest too. Why: a subtask segment ends where the next one starts at rest;
        # a supported object still moving at a segment's last knot was stitched to the next
        # segment's zero velocity, and the whole horizon then broke its dynamics row (S1's placed
        # box: 0.23 at the knot before the boundary)
        for j in self.midx.values():
            setb(f"o{j}_vel", N, 0, 0)
        lbw[:, K] = 0
        ubw[:, K] = 0

        # ---------------- rows
        # last window: integration rows off; momentum rows stay on against the (zero) dummy knot,
        # i.e. the final knot is in static equilibrium (the motion ends at rest)
        trans = ["kinematic integration", "CoM integration"]
        torque_margins = self._torque_margins()
        for k in range(K):
            last = k == N
            for r in trans:
                if last:
                    rows(r, k, -INF, INF)
            for f in FEET:
                c = self.contact(k, f)
                cn = self.contact(k + 1, f) if not last else None
                if c is None:
                    rows(f"{f} on surface", k, 0, INF)  # above ground
                    # a swing sole stays nearly level (|tilt| <= SWING_TILT): the sole centre is
                    # kept above ground, and a pitched foot would put its heel or toe into the floor
                    rows(f"{f} orientation aligned with surface", k, -SWING_TILT, SWING_TILT)
                    rows(f"{f} inside contact patch", k, -INF, INF)
                else:
                    he = self._patch_half(c)
                    rows(f"{f} inside contact patch", k, -he, he)
                    if k == 0:  # the start is given: see _initial_tilt
                        tilt = self._initial_tilt(f)
                        rows(f"{f} orientation aligned with surface", k, np.minimum(tilt, 0), np.maximum(tilt, 0))
                if c is None or last or (cn is not None and cn.object_id != c.object_id):
                    rows(f"{f} no slip", k, -INF, INF)
                elif cn is not None:  # stance -> stance: z is held by both knots' "on surface" rows
                    rows(f"{f} no slip", k, [0, 0, -INF, 0], [0, 0, INF, 0])
                # else lift-off: the last contact force acts until t_k+1, so the sole is still
                # planted there (xyz and yaw); without this the first swing knot could be 15 cm
                # ahead while the interval before it carried 270 N (S1), which no controller can track
                rows(f"{f} friction cone", k, 0 if c is not None else -INF, INF)
            for h in HANDS:
                ch = self.contact(k, h)
                chn = None if last else self.contact(k + 1, h)
                if ch is None:
                    rows(f"{h} contact position", k, -INF, INF)
                if ch is None or last or chn is not None:
                    rows(f"{h} release: still at the contact", k, -INF, INF)
                if ch is None or chn is None or chn.object_id != ch.object_id:
                    rows(f"{h} grip: no rotation on the surface", k, -INF, INF)
                rows(f"{h} friction cone", k, 0 if ch is not None else -INF, INF)
                rows(f"{h} patch moment", k, 0 if ch is not None else -INF, INF)
            for oid, j in self.midx.items():
                mode = self.obj_mode(k, oid)
                if last:
                    rows(f"o{j} kinematic integration", k, -INF, INF)
                held_at_rest = self.resting_under_hands(k, oid)  # its support's forces hold what the hands do
                if mode == "attached" or (mode == "fixed" and not held_at_rest):
                    rows(f"o{j} linear dynamics", k, -INF, INF)
                    rows(f"o{j} angular dynamics", k, -INF, INF)
                prev = self.obj_mode(k - 1, oid) if k > 0 else "fixed"
                # fixed objects: pose constant through the integration rows; the resting rows are
                # only needed at the first fixed knot after a motion (else they are dependent rows)
                placed = mode == "fixed" and prev != "fixed"
                if mode not in ("supported", "rolling") and not placed:
                    rows(f"o{j} support contact (on surface, aligned)", k, -INF, INF)
                rows(f"o{j} support friction cone", k, 0 if mode in ("supported", "rolling") or held_at_rest else -INF, INF)
                # only while carried: resting, the support row already holds the corners at the surface
                rows(f"o{j} above the floor", k, 0 if mode == "free" else -INF, INF)
                if mode != "rolling":
                    rows(f"o{j} rolling: no longitudinal wheel force", k, -INF, INF)
                    rows(f"o{j} rolling: resistance opposes motion", k, -INF, INF)
                    rows(f"o{j} nonholonomic: no lateral slip", k, -INF, INF)
                else:  # up to the wheels' rolling resistance: the hands cannot pull to stop it
                    f_rr = WHEEL_ROLLING_RESISTANCE / (m.mass * G)
                    rows(f"o{j} rolling: no longitudinal wheel force", k, -f_rr, f_rr)
                    rows(f"o{j} rolling: resistance opposes motion", k, -INF, 0)
                if mode != "attached":
                    rows(f"o{j} attachment", k, -INF, INF)
                hs = self._support_bounds(k, oid)
                rows(f"o{j} over its support", k, -hs, hs)
                tol = self._placement_tolerance(k, oid)
                rows(f"o{j} at its placement goal", k, -tol, tol)
            for i, (s, (oid, pi)) in enumerate(self.pairs):
                on = self._pair_enabled(k, s, oid)
                rows(f"c{i} collision", k, self._clearance(s, k, oid) if (hard and on) else -INF, INF)
                rows(f"c{i} homotopy surrogate", k, 0 if (homotopy is True and self._surrogate_on(k, s, oid)) else -INF,
                     INF)
            for (a, b) in win.st.self_pairs:  # an arm-body pair holds while its hand is free
                side = self._arm_body_side.get((a, b))
                on = hard and (side is None or self.contact(k, f"{side}_hand") is None)
                rows(f"self {a} {b}", k, 0 if on else -INF, INF)
            for i, (oid, _, _) in enumerate(self.env_pairs):  # hard in every stage: no surrogate
                rows(f"e{i} carried object collision", k, 0 if self._env_enabled(k, oid) else -INF, INF)
            rows("floor clearance", k, 0, INF)  # smooth, so on in every homotopy stage
            rows("hip roll coupling", k, 0 if k > 0 else -INF, INF)  # knot 0 is the measured start
            if win.st.interval_momentum:
                tol = INF if last else opt.interval_momentum_tolerance / m.mass
                rows("angular momentum across the interval", k, -tol, tol)
            if win.st.upper_body_acceleration:
                dv = INF if last else opt.upper_body_acceleration_limit * (self.grid.t[k + 1] - self.grid.t[k])
                rows("upper-body acceleration", k, -dv, dv)
            self._support_rows(k, last, rows)
            rows("feet apart", k, FEET_MIN_LATERAL if k > 0 else -INF, INF)  # knot 0 is the measured start
            # |tau| <= margin tau_max: quasi-static rows leave out the distal links' inertia
            rows("joint torques", k, -torque_margins, torque_margins)

        # ---------------- parameters
        kf_sub = {kf.subtask_index: kf for kf in prob.keyframes}
        for k in range(K):
            ph = prob.phases[self.grid.phase[k]]
            col = Pm[:, k]

            def sp(name, val):
                col[P[name]] = val

            sp("dt", t[k + 1] - t[k] if k < N else t[N] - t[N - 1])
            sp("w_stage", 1.0 / N)
            sp("b_st", 1.0 if ph.phase_type == STANCE else 0.0)
            for key in ("w_post", "w_xd", "w_acc", "w_force", "w_force_rate", "w_st_com", "w_st_vel", "w_wk_base",
                        "w_upright", "w_slack", "w_self", "mu_hand", "self_margin", "hip_margin"):
                sp(key, w[key])
            if k == N:   # the knot after the last is a zero dummy, not a change of load
                sp("w_force_rate", 0.0)
            sp("mu_foot", w["mu_foot"] / math.sqrt(2))  # inner pyramid of the cone
            sp("mu_hand", w["mu_hand"] / math.sqrt(2))
            sp("mu_obj", w["mu_obj"] / math.sqrt(2))
            xref = self.x_guess[k].copy()
            sp("x_ref", xref)
            if k == 0:
                sp("w_anchor", w["w_anchor"])
                sp("x_ref", self.x_init)
            kf = self.kf_knots.get(k)
            if kf is not None and opt.use_keyframe_base_cost:
                sp("x_kf", kf.x())
                sp("w_kfb_z", w["w_kfb_z"])
                sp("w_kfb_th", w["w_kfb_th"])
            kfs = kf_sub.get(ph.subtask_index)
            # eq. (2) pulls the feet to the keyframe's stance on the way to it, not after it: after a
            # grasp keyframe the feet walk with a pushed trolley (held back here, S2 never pushed)
            if (opt.use_keyframe_foot_cost and kfs is not None and kfs.desired_foot_xy is not None
                    and ph.phase_type == STANCE and t[k] <= prob.keyframe_time(kfs) + 1e-9):
                sp("w_kff", w["w_kff"])
                sp("foot_des", np.asarray(kfs.desired_foot_xy, float))
            for f in FEET:
                c = self.contact(k, f)
                if c is not None:
                    sp(f"{f}_h", self._surface_height(c))
                    sp(f"{f}_patch", self._patch_frame(c))
                else:
                    sp(f"{f}_h", 0.0)
                    sp(f"{f}_patch", [0, 0, 1, 0])
                    sp(f"{f}_w_swing", w["w_swing"])
                    sp(f"{f}_swing_h", self._swing_height(k, f))
            for h in HANDS:
                self._hand_params(k, h, col, P)
            for oid, j in self.midx.items():
                self._object_params(k, oid, j, col, P)
            for i, (s, (oid, pi)) in enumerate(self.pairs):
                self._pair_params(k, i, s, oid, pi, col, P, expo, penalty, homotopy, hard)
            for i in range(len(self.env_pairs)):
                self._env_params(i, col, P)

        # ---------------- warm start
        W0 = np.zeros((W.n, K + 1))
        X = self.x_guess
        for k in range(K):
            W0[W["x"], k] = X[k]
            if k < N:
                xd = (X[k + 1] - X[k]) / max(t[k + 1] - t[k], 1e-3) if k + 1 < K else np.zeros(35)
            else:
                xd = np.zeros(35)
            W0[W["x"], k] = X[k]
        for k in range(1, K):
            W0[W["xd"], k] = (X[k] - X[k - 1]) / max(t[k] - t[k - 1], 1e-3)
        W0[W["xd"], 0] = 0
        W0[W["xd"], N] = 0
        for k in range(K):
            num = m.numeric(X[k], W0[W["xd"], k])
            W0[W["com"], k] = num["com"]
            W0[W["comd"], k] = num["h"][:3] / m.mass
            W0[W["kk"], k] = num["h"][3:] / m.mass
            nf = sum(self.contact(k, f) is not None for f in FEET)
            for f in FEET:
                if self.contact(k, f) is not None:
                    W0[W[f"u_{f}"], k] = np.tile([0, 0, 1.0 / (4 * nf)], 4)
            # hands carrying a free object: share its weight (warm start only)
            for h in HANDS:
                c = self.contact(k, h)
                if c is not None and c.object_id in self.midx and self.obj_mode(k, c.object_id) == "free":
                    nh = sum(1 for hh in HANDS if self.contact(k, hh) is not None
                             and self.contact(k, hh).object_id == c.object_id)
                    mo = self._lumped(k, c.object_id)[0]
                    W0[W[f"u_{h}"], k] = np.array([0, 0, -mo / (nh * m.mass)]) * 1.0
            for oid, j in self.midx.items():
                W0[W[f"o{j}_pose"], k] = self.obj_nom[oid][k]
                if k > 0 and self.obj_mode(k, oid) != "fixed" and self.obj_mode(k - 1, oid) != "fixed":
                    W0[W[f"o{j}_vel"], k] = (self.obj_nom[oid][k] - self.obj_nom[oid][k - 1]) / (t[k] - t[k - 1])
        self._pushing_forces(W0, W)
        W0 = np.clip(W0, lbw, ubw)
        return lbw, ubw, lbg, ubg, Pm, W0

    def _support_rows(self, k: int, last: bool, rows) -> None:
        """Margins of balance the Options ask for (off by default): the CoM over the sole of a
        single stance, and the CMP near the centre of pressure (small rate of angular momentum)."""
        opt = self.prob.options
        for f in FEET:
            rows(f"{f} CoM over the sole", k, -INF, INF)
        rows("angular momentum rate (CMP offset)", k, -INF, INF)
        rows("CoM inside the double stance", k, -INF, INF)
        stance = [f for f in FEET if self.contact(k, f) is not None]
        if len(stance) == 2 and opt.double_support_com_margin is not None:
            # along: the force points' span less the margin; across: the sole's force points
            along = self.sole_force_points[:, 0] - SOLE_CENTER[0]
            across = self.sole_force_points[:, 1] - SOLE_CENTER[1]
            m = opt.double_support_com_margin
            rows("CoM inside the double stance", k, [along.min() + m, -INF, across.min() + m, -INF],
                 [INF, along.max() - m, INF, across.max() - m])
        if len(stance) == 1 and (opt.single_support_com_margin is not None
                                 or opt.single_support_com_lateral is not None):
            along = self.sole_force_points[:, 0] - SOLE_CENTER[0]
            m_al = INF if opt.single_support_com_margin is None else opt.single_support_com_margin
            m_lat = INF if opt.single_support_com_lateral is None else opt.single_support_com_lateral
            rows(f"{stance[0]} CoM over the sole", k, [along.min() - m_al, -m_lat], [along.max() + m_al, m_lat])
        if opt.max_cmp_offset > 0 and not last:
            rows("angular momentum rate (CMP offset)", k, -opt.max_cmp_offset, opt.max_cmp_offset)

    def _pushing_forces(self, W0: np.ndarray, W) -> None:
        """Warm-start forces of an object that rolls or slides while hands hold it: its supports
        carry its weight, the hands give its nominal horizontal acceleration (Newton's third law on
        the robot's side).

        Why: with zero forces the nominal push violated the object's dynamics by 2 (scaled), and
        ipopt restored feasibility by stopping the object: every push converged with the trolley
        where it started and the hands at 0 N."""
        t, mg = self.grid.t, self.model.mass * G
        for k in range(self.grid.K - 1):
            for oid, j in self.midx.items():
                if self.obj_mode(k, oid) not in ("rolling", "supported") and not self.resting_under_hands(k, oid):
                    continue
                mo = self._lumped(k, oid)[0]
                W0[W[f"o{j}_us"], k] = np.tile([0.0, 0.0, mo * G / (4 * mg)], 4)
                hands = [h for h in HANDS if (c := self.contact(k, h)) is not None and c.object_id == oid]
                if not hands:
                    continue
                dv = (W0[W[f"o{j}_vel"], k + 1][:2] - W0[W[f"o{j}_vel"], k][:2]) / (t[k + 1] - t[k])
                for h in hands:
                    W0[W[f"u_{h}"], k][:2] = -mo * dv / (len(hands) * mg)

    # ------------------------------------------------------------------ helpers
    def _surface(self, c):
        """(height, centre xy, yaw, half extents xy) of the surface a foot touches."""
        if c.object_id == FLOOR:
            r = float(self.prob.options.foothold_radius)
            if c.position is not None and 0.0 < r < INF:  # a square round the schedule's foothold
                return 0.0, np.asarray(c.position[:2], float), 0.0, np.full(2, r + SOLE_EDGE_MARGIN)
            return 0.0, np.zeros(2), 0.0, np.array([INF, INF])
        o = self.prob.object(c.object_id)
        pose = np.concatenate([np.asarray(o.position, float), o.rpy()])
        if c.object_id in self.obj_nom:  # moved earlier: use its nominal resting pose at that time
            pose = self._nominal_pose_at_contact(c)
        return pose[2] + o.top_z(), pose[:2], pose[5], o.footprint_half()

    def _nominal_pose_at_contact(self, c):
        poses = self.support_poses.get(c.object_id, self.obj_nom[c.object_id])
        for k in range(self.grid.K):
            if self.contact(k, "left_foot") is c or self.contact(k, "right_foot") is c:
                return poses[k]
        return poses[-1]

    def use_solved_support_poses(self, poses: dict) -> None:
        """Feet on a moved object stand on its solved pose (object id -> (K, 6) p, rpy per knot)
        instead of its nominal one.

        Why: the patch and height rows of a foot on an object take the surface as a parameter. A
        subtask segment starts with each object where the previous segment left it, so its rows use
        the real pose; the whole problem's nominal pose is the placement goal, a few mm to cm away.
        Evaluating the stitched segments with the nominal surface reported S1's foot on the box
        5 mm outside its patch when it was inside the box as placed."""
        self.support_poses = {oid: np.asarray(p, float) for oid, p in poses.items()}

    def _surface_height(self, c):
        return self._surface(c)[0]

    def _patch_frame(self, c):
        _, xy, yaw, _ = self._surface(c)
        return [xy[0], xy[1], math.cos(yaw), math.sin(yaw)]

    def _patch_half(self, c):
        he = self._surface(c)[3]
        # the sole centre must stay 6 cm inside the surface edges (sole half-width ~3 cm)
        return np.maximum(he - SOLE_EDGE_MARGIN, 0.0)

    def _swing_height(self, k, f):
        K = self.grid.K
        k0 = k
        while k0 > 0 and self.contact(k0, f) is None:
            k0 -= 1
        if self.contact(k0, f) is not None and k0 < k:
            k0 += 1  # the lift-off knot is still planted (see the no-slip rows): the swing starts there
        k1 = k
        while k1 < K - 1 and self.contact(k1, f) is None:
            k1 += 1
        c0, c1 = self.contact(k0, f), self.contact(k1, f)
        h0 = self._surface_height(c0) if c0 is not None else 0.0
        h1 = self._surface_height(c1) if c1 is not None else 0.0
        s = (self.grid.t[k] - self.grid.t[k0]) / max(self.grid.t[k1] - self.grid.t[k0], 1e-6)
        top = max(h0, h1) + self.w["swing_clearance"]
        # rise to 'top' in the first 40 % of the swing, stay, come down in the last 40 %: smoothsteps,
        # so the foot leaves and lands at rest (the earlier sine bump clipped at 1.6x put a foot 61 %
        # of the way up to S1's box top 0.1 s after lift-off, and the TO whipped the hips to follow)
        bump = min(smoothstep(s / 0.4), smoothstep((1.0 - s) / 0.4))
        base = (1 - s) * h0 + s * h1
        return base + (top - base) * bump

    def _hand_params(self, k, h, col, P):
        c = self.contact(k, h)
        n_obj = len(self.moving)
        sel = np.zeros(n_obj + 1)
        if c is None:
            col[P[f"{h}_sel"]] = sel
            col[P[f"{h}_grip_axes"]] = np.eye(3).reshape(-1)
            col[P[f"{h}_n"]] = [0, 0, 1]
            col[P[f"{h}_t1"]] = [1, 0, 0]
            col[P[f"{h}_t2"]] = [0, 1, 0]
            return
        # first knot of this contiguous contact with the same object: grip defined there
        k0 = k
        while k0 > 0 and self.contact(k0 - 1, h) is not None and self.contact(k0 - 1, h).object_id == c.object_id:
            k0 -= 1
        c0 = self.contact(k0, h)
        pos = np.asarray(c0.position, float)
        n = np.asarray(c0.normal, float)
        n = n / np.linalg.norm(n)
        if c.object_id in self.midx:
            j = self.midx[c.object_id]
            sel[j + 1] = 1
            pose = self.obj_nom[c.object_id][k0]
            R = rpy_to_rot(pose[3:])
            loc = R.T @ (pos - pose[:3])
            n = R.T @ n
        else:
            sel[0] = 1
            loc = pos
        a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
        t1 = np.cross(n, a)
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        col[P[f"{h}_sel"]] = sel
        col[P[f"{h}_loc"]] = loc
        col[P[f"{h}_grip_axes"]] = grip_axes(n).reshape(-1, order="F")
        col[P[f"{h}_n"]] = n
        col[P[f"{h}_t1"]] = t1
        col[P[f"{h}_t2"]] = t2

    def _lumped(self, k, oid):
        """Mass and body inertia of object oid plus objects attached to it at knot k."""
        o = self.prob.object(oid)
        mass = o.mass
        I = o.inertia_matrix().copy()
        for other, jj in self.midx.items():
            ph = self.prob.phases[self.grid.phase[k]]
            mo = ph.objects.get(other)
            if mo is not None and mo.mode == "attached" and mo.attached_to == oid:
                oo = self.prob.object(other)
                off = self._attach_offset(k, other, oid)[:3]
                mass += oo.mass
                I = I + oo.inertia_matrix() + oo.mass * (np.dot(off, off) * np.eye(3) - np.outer(off, off))
        return mass, I

    def _attach_offset(self, k, oid, carrier):
        k0 = k
        while k0 > 0 and self.obj_mode(k0 - 1, oid) == "attached":
            k0 -= 1
        pc = self.obj_nom[carrier][k0]
        po = self.obj_nom[oid][k0]
        Rc = rpy_to_rot(pc[3:])
        return np.concatenate([Rc.T @ (po[:3] - pc[:3]), [po[5] - pc[5]]])

    def _object_params(self, k, oid, j, col, P):
        o = self.prob.object(oid)
        mode = self.obj_mode(k, oid)
        mass, I = self._lumped(k, oid)
        col[P[f"o{j}_m"]] = mass
        if self.structure.load_in_support:   # carried: free in the phase and in a hand
            col[P[f"o{j}_held"]] = float(mode == "free" and any(
                (c := self.contact(k, h)) is not None and c.object_id == oid for h in HANDS))
        col[P[f"o{j}_I"]] = I.ravel(order="F")
        col[P[f"o{j}_corners"]] = o.bottom_corners().ravel()
        col[P[f"o{j}_axle"]] = np.asarray(o.rear_axle, float)
        ph = self.prob.phases[self.grid.phase[k]]
        mo = ph.objects.get(oid)
        if mode in ("supported", "rolling"):
            col[P[f"o{j}_zrest"]] = self.rest_height(oid, mo.support)
        else:  # set down on a top: on it, not at the nominal's height (SUPPORT_MATCH off)
            hit = self._support_cache.get((k, oid))
            col[P[f"o{j}_zrest"]] = self.obj_nom[oid][k][2] if hit is None else hit[2]
        if mode == "attached":
            sel = np.zeros(len(self.moving))
            sel[self.midx[mo.attached_to]] = 1
            col[P[f"o{j}_att_sel"]] = sel
            col[P[f"o{j}_att_off"]] = self._attach_offset(k, oid, mo.attached_to)
        col[P[f"o{j}_w_reg"]] = self.w["w_obj_reg"]
        col[P[f"o{j}_w_acc"]] = (self.w["w_obj_acc"] if mode in ("supported", "rolling")
                                 else self.w["w_carry_acc"] if mode == "free" else 0.0)
        col[P[f"o{j}_w_aacc"]] = self.w["w_carry_aacc"] if mode == "free" else 0.0
        if mode == "free":
            col[P[f"o{j}_w_pose"]] = self.w["w_carry_pose"]
            # the blend's own relative yaw: the stepping guess's base yaw swings with each step
            rel = self.carry_rel.get(oid)
            if rel is not None and np.all(np.isfinite(rel[k])):
                col[P[f"o{j}_yaw_rel"]] = math.remainder(rel[k][5], 2 * math.pi)
                col[P[f"o{j}_w_offset"]] = self.w["w_carry_offset"]
                col[P[f"o{j}_offset"]] = rel[k][1:3]
            else:  # not on a blended carry (no keyframe warm start): the guess's relative yaw
                col[P[f"o{j}_yaw_rel"]] = math.remainder(self.obj_nom[oid][k][5] - self.x_guess[k][5], 2 * math.pi)
        sup = self.support_under(k, oid)
        if sup is not None:
            self._primitive_params(f"o{j}_sup", *sup, col, P)
        for g in self.prob.placement_goals:
            if g.object_id != oid:
                continue
            kg = self.goal_knot(g)
            held_after = self.prob.options.hold_placement_goals and mode == "free" and k > kg
            if k in (kg, self.grid.K - 1) or held_after:   # held_after: Options.hold_placement_goals
                col[P[f"o{j}_w_goal"]] = g.weight
                col[P[f"o{j}_goal"]] = [*g.position, g.yaw]

    def _clearance(self, s: int, k: int | None = None, oid: str | None = None) -> float:
        """Least distance (m) the hard collision row keeps sphere ``s`` from an object's
        primitives: LEG_OBJECT_CLEARANCE for feet and shins, else 0; while ``oid`` is carried at
        knot ``k``, at least Options.carried_object_clearance for every sphere but the hands' and
        forearms' (they hold it); with Options.forearm_clear_of_held_object, -HELD_OBJECT_FOREARM_DEPTH
        (less Options.hand_standoff) for a forearm sphere against the object its hand holds;
        Options.body_object_clearance for the pelvis, torso, head and thigh spheres;
        Options.hand_object_clearance for the hand spheres against still objects no hand touches."""
        grp = self.model.spheres[s].group
        if self.prob.options.forearm_clear_of_held_object and grp.endswith("_forearm") and k is not None \
                and self._hand_holds(k, grp.split("_")[0], oid):
            # a hand standing off the face (Options.hand_standoff) has already taken its wrist that far out
            return -max(HELD_OBJECT_FOREARM_DEPTH - self.prob.options.hand_standoff, 0.0)
        out = LEG_OBJECT_CLEARANCE if grp.endswith(("_foot", "_shin")) else 0.0
        if grp in ("pelvis", "torso", "head") or grp.endswith("_thigh"):
            out = max(out, self.prob.options.body_object_clearance)
        if grp.endswith("_hand") and oid not in self._hand_touched:
            out = max(out, self.prob.options.hand_object_clearance)
        carried = self.prob.options.carried_object_clearance
        if carried > 0 and k is not None and not grp.endswith(("_hand", "_forearm")) \
                and self.obj_mode(k, oid) == "free":
            out = max(out, carried)
        return out

    def _surrogate_on(self, k, s, oid) -> bool:
        """The pair's homotopy surrogate applies: the pair is on, and it is not a forearm against the
        object its hand holds. The surrogate (an ellipsoid through the box's corners) reaches 8 cm past
        a 0.4 m box's side face: the guide could then only keep the wrist out of it by turning the
        hand off the face, and the final stage kept that turn"""
        return self._pair_enabled(k, s, oid) and self._clearance(s, k, oid) >= 0.0

    def _hand_holds(self, k: int, side: str, oid: str) -> bool:
        """Whether hand ``side`` touches ``oid`` at knot ``k`` or the knot before (the release knot)."""
        limb = f"{side}_hand"
        near = [self.contact(k, limb)] + ([self.contact(k - 1, limb)] if k > 0 else [])
        return any(c is not None and c.object_id == oid for c in near)

    def _pair_enabled(self, k, s, oid) -> bool:
        side, _, part = self.model.spheres[s].group.partition("_")
        # hands: off while the hand touches the object and at the knot it lets go (the release row
        # keeps it at the contact there); on at the knot before a touch, so the hand comes from
        # outside: with it off there, S1's left hand came over the box's top edge (123 mm into it on
        # the sim's meshes, the executed robot fell) and S2's wrist was 118 mm inside the box. The
        # forearm goes with the hand unless Options.forearm_clear_of_held_object
        held = ("hand",) if self.prob.options.forearm_clear_of_held_object else ("hand", "forearm")
        if part in held:
            return not self._hand_holds(k, side, oid)
        # feet keep the older rule (off the knot before touchdown too): with the hands' rule for
        # the feet as well, S1's subtask 2 (step onto the box) stopped at its iteration cap
        if part == "foot":
            limb = f"{side}_foot"
            near = [k - 1, k, k + 1] if k > 0 else [k, k + 1]
            return not any((c := self.contact(j, limb)) is not None and c.object_id == oid
                           for j in near if j < self.grid.K)
        return True

    def _homotopy_weight(self, homotopy) -> float:
        """Weight of the surrogate's penalty: with slacks (``True``) w_hom on (w_slack s^2 +
        max(1 - F, 0)^2); without (``"penalty"``) the same minimum over s, w_hom (w_slack + 1)
        max(1 - F, 0)^2."""
        if homotopy is True:
            return self.w["w_hom"]
        if homotopy == "penalty":
            return self.w["w_hom"] * (self.w["w_slack"] + 1.0)
        return 0.0

    def _primitive_params(self, tag: str, oid: str, pi: int, col, P) -> np.ndarray:
        """Fill a collision pair's primitive parameters (``<tag>_sel``, ``_pose``, ``_loc``: see
        transcription._primitive_frame); returns the primitive's half extents."""
        o = self.prob.object(oid)
        pr = o.primitives[pi]
        sel = np.zeros(len(self.moving) + 1)
        if oid in self.midx:
            sel[self.midx[oid] + 1] = 1
            col[P[f"{tag}_loc"]] = [*pr.position, math.cos(pr.yaw), math.sin(pr.yaw)]
            col[P[f"{tag}_pose"]] = np.concatenate([np.zeros(3), np.eye(3).ravel()])
        else:
            sel[0] = 1
            c, R, _ = obj_prims_world(o)[pi]
            col[P[f"{tag}_pose"]] = np.concatenate([c, R.ravel(order="F")])
            col[P[f"{tag}_loc"]] = [0, 0, 0, 1, 0]
        col[P[f"{tag}_sel"]] = sel
        return pr.half_extents()

    def _pair_params(self, k, i, s, oid, pi, col, P, expo, penalty, homotopy, hard=True):
        half = self._primitive_params(f"c{i}", oid, pi, col, P)
        # a stage without the hard rows (the homotopy guide) keeps the clearance they will ask for
        # in its surrogate and penalty: the primitive grows by it.  Without it S1's subtask 0 guide
        # ended with the shins 1.6 cm into the box (the grasp keyframe's posture has them 8 cm in),
        # 4.6 cm short of the final stage's 3 cm leg clearance; that stage then started cold, its
        # barrier stuck at 0.8 for 300 iterations, and it stopped "locally infeasible"
        col[P[f"c{i}_half"]] = half + (0.0 if hard else self._clearance(s, k, oid))
        on = self._pair_enabled(k, s, oid)
        col[P[f"c{i}_w"]] = [self.w["w_pen"] if (penalty and on) else 0.0,
                             self._homotopy_weight(homotopy) if self._surrogate_on(k, s, oid) else 0.0, expo]
