"""Direct transcription of the whole-body TO as ONE symbolic knot window, mapped over the horizon.

Formulation (Dai, Valenzuela, Tedrake 2014: centroidal dynamics + full kinematics)
---------------------------------------------------------------------------------
Knot variables ``w_k`` (identical layout at every knot):
  x (35: base p, base rpy, 29 joints), xd = dx/dt (35), CoM r (3), CoM velocity c (3; linear
  momentum = m c), angular momentum about the CoM divided by the robot mass kk (3), four corner
  forces per foot sole (24) and one force per hand (6), all forces in units of the robot weight
  m g, and per moving object: pose (p, rpy), rates (v, rpy rates), four support corner forces
  (units of m g) and one slack per object-collision pair (homotopy constraint).

Window ``k`` couples (w_k, w_{k+1}) with a parameter column p_k and returns constraint rows and a
cost.  Dynamics rows (k -> k+1, explicit in forces, symplectic in positions):
  x_{k+1} = x_k + dt xd_{k+1};  r_{k+1} = r_k + dt c_{k+1}
  c_{k+1} - c_k = dt g (sum u_k - e_z)                         (Newton, linear momentum)
  kk_{k+1} - kk_k = dt g sum (p_i - r_k) x u_i,k                (Euler, angular momentum)
Knot rows: r_k = CoM(x_k); [m c_k; m kk_k] = A(x_k) xd_k (centroidal momentum matrix).
Contacts: sole on the surface plane and level (patch orientation), centre inside the surface
rectangle, no slip between knots (xy and yaw; at lift-off also z: the force u_k of the last
contact knot acts over [t_k, t_k+1], so the sole stays planted until t_k+1), corner forces in a linearised (inner pyramid)
friction cone; hands: point on the object (relative to the object's pose when it moves), orientation
on the object held from knot to knot (a sticking patch), force in the linearised cone of the object's
surface normal and a patch moment; the object receives the opposite wrench (Newton's third law).
Objects: single rigid bodies (linear + angular momentum), supported/rolling patch contacts,
nonholonomic rear axle, rigid attachment.
Joint torques: the 26 hip-to-ankle and shoulder-to-wrist joints and the 3 waist joints,
quasi-static (gravity of the links beyond the joint plus the contact wrenches they carry; the distal
links' inertia is left out and covered by a margin), within a fraction of the G1's limits; the waist
rows also carry the inertia of the torso and arms (rate of their momentum, knot k to k+1).
Collisions: robot spheres vs object boxes: hard constraint on the exact signed distance, quadratic
penalty on penetration, and a homotopy on a super-ellipsoid surrogate whose exponent is raised
between solves (2 = ellipsoid -> box): either rows F - 1 + s >= 0 with a penalised slack per pair,
or the penalty they amount to, with the slacks pinned at 0 (``Options.homotopy_form``, by default
the penalty where an object is carried while walking; ``discretize.ProblemData._homotopy_weight``);
self-collision sphere pairs (hard + penalty).

Rows that do not apply at a knot get infinite bounds; forces that do not apply get zero bounds, so
one window Function serves every knot and its derivatives are built once (see ``solver.py``).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .hip_coupling import hip_roll_clearance
from .layout import Layout, sx_split
from .model import COP_MARGIN, FEET, GRAVITY, HANDS, G1Model, rpy_rate_matrix, rpy_to_rot, rot_z, sole_force_points

G = 9.81

#: window rows of the collision pairs (robot-object hard and surrogate rows, carried-object rows,
#: self-collision rows): their curvature is evaluated only where it is not zero (assembly)
_COLLISION_ROW = re.compile(r"(c\d+) (?:collision|homotopy surrogate)|(e\d+) carried object collision|(self \d+ \d+)")


@dataclass(frozen=True)
class CollisionGroup:
    """One collision pair's window rows and penalty: zero curvature wherever its multipliers and
    ``active`` are zero (assembly.WindowDerivatives evaluates it only where they are not)."""

    name: str
    rows: np.ndarray      # window-row indices
    penalty: ca.SX        # its share of the cost
    active: ca.SX         # nonzero where the penalty or its derivatives may be


#: half size (m) of the hand contact patch (the G1 hand's palm pressed on a face) and the torsional
#: friction coefficient times its effective radius (m): bounds of the hand patch moment
HAND_PATCH_HALF = 0.03
HAND_TORSION = 0.01
#: scale of the hand moments in the force regulariser: a moment is used only where the task needs
#: it (with 10, the push's hands carried moments that the wrists could not hold: torque check failed)
HAND_MOMENT_COST = 100.0
#: scale of the wheels' dissipation rows (force in robot weights x velocity in m/s is ~1e-3)
ROLLING_DISSIPATION_SCALE = 100.0
#: a hand contact whose normal (object frame) is this close to a face axis sits on a flat face
FLAT_FACE_COS = 0.99

#: the waist and arm joints' entries of xd (base 0:6, legs 6:18): the upper-body speed bounds and
#: acceleration rows act on these, the legs stay free for stepping
UPPER_BODY_XD = slice(18, 35)


def grip_axes(n_local) -> np.ndarray:
    """3 x 3 projector onto the rotations a hand's grip holds on a surface of normal ``n_local``
    (object frame). On a flat face it holds all three (identity). On a bar, whose surface normal is
    oblique to the object's faces and square to one axis (the trolley's handle, a cylinder), the
    hand may roll about that axis: the projector leaves it out."""
    n = np.asarray(n_local, float)
    n = n / np.linalg.norm(n)
    if np.max(np.abs(n)) >= FLAT_FACE_COS:
        return np.eye(3)
    i = int(np.argmin(np.abs(n)))
    if abs(n[i]) > 1.0 - FLAT_FACE_COS:
        return np.eye(3)
    a = np.eye(3)[i]
    return np.eye(3) - np.outer(a, a)


@dataclass(frozen=True)
class Structure:
    """What fixes the symbolic window: number of moving objects and collision pair structure."""

    n_obj: int
    obj_pairs: tuple  # sphere index per object-collision pair
    self_pairs: tuple  # (sphere i, sphere j)
    #: torque-row groups (model.torque_row_joints) whose rows also carry the inertia of the links
    #: beyond the joint (Options.inertial_torque_groups)
    inertial_groups: tuple
    #: rows of the angular momentum across each interval (Options.interval_momentum_tolerance > 0)
    interval_momentum: bool = False
    #: rows of the upper body's acceleration (Options.upper_body_acceleration_limit > 0)
    upper_body_acceleration: bool = False
    #: number of carried-object clearance pairs (a point sphere on a moving object against another
    #: object's primitive; discretize.ProblemData.env_pairs)
    env_pairs: int = 0
    #: the double-stance CoM rows count the carried objects' weight (Options.load_in_double_support_margin)
    load_in_support: bool = False
    #: m the soles' toe-side force points lie inside the toe edge (Options.cop_margin_front)
    cop_margin_front: float = float(COP_MARGIN[0])
    #: m a touching hand's point stays outside the surface, its force at the surface (Options.hand_standoff)
    hand_standoff: float = 0.0
    #: m the soles' force points lie inside the sole's sides (Options.cop_margin_side)
    cop_margin_side: float = float(COP_MARGIN[1])

    def key(self) -> str:
        return hashlib.sha1(repr(self).encode()).hexdigest()[:12]


def var_layout(st: Structure) -> Layout:
    L = Layout("w")
    L.add("x", 35)
    L.add("xd", 35)
    L.add("com", 3)
    L.add("comd", 3)
    L.add("kk", 3)
    for f in FEET:
        L.add(f"u_{f}", 12)
    for h in HANDS:
        L.add(f"u_{h}", 3)
    for h in HANDS:
        L.add(f"tau_{h}", 3)  # patch moment about the hand point (units of m g x 1 m)
    for j in range(st.n_obj):
        L.add(f"o{j}_pose", 6)
        L.add(f"o{j}_vel", 6)
        L.add(f"o{j}_us", 12)
    L.add("slack", len(st.obj_pairs))
    return L


def par_layout(st: Structure) -> Layout:
    P = Layout("p")
    for k in ("dt", "w_stage", "b_st", "w_post", "w_xd", "w_acc", "w_force", "w_force_rate", "w_st_com", "w_st_vel",
              "w_kff", "w_wk_base", "w_upright", "w_anchor", "w_kfb_z", "w_kfb_th", "w_slack",
              "w_self", "mu_foot", "mu_hand", "mu_obj", "self_margin", "hip_margin"):
        P.add(k, 1)
    P.add("x_ref", 35)
    P.add("x_kf", 35)
    P.add("foot_des", 2)
    for f in FEET:
        P.add(f"{f}_h", 1)  # surface height (contact) / ground height (swing)
        P.add(f"{f}_patch", 4)  # centre xy, cos, sin of the surface rectangle yaw
        P.add(f"{f}_w_swing", 1)
        P.add(f"{f}_swing_h", 1)
    for h in HANDS:
        P.add(f"{h}_sel", st.n_obj + 1)
        P.add(f"{h}_loc", 3)
        P.add(f"{h}_n", 3)
        P.add(f"{h}_t1", 3)
        P.add(f"{h}_t2", 3)
        P.add(f"{h}_grip_axes", 9)  # 3 x 3 (column-major): rotations of the grip that are held
        P.add(f"{h}_w_track", 1)
    for j in range(st.n_obj):
        P.add(f"o{j}_m", 1)
        if st.load_in_support:
            P.add(f"o{j}_held", 1)   # 1 where the hands carry it: counted in the support rows
        P.add(f"o{j}_I", 9)
        P.add(f"o{j}_corners", 12)
        P.add(f"o{j}_axle", 3)
        P.add(f"o{j}_zrest", 1)
        P.add(f"o{j}_att_sel", st.n_obj)
        P.add(f"o{j}_att_off", 4)
        P.add(f"o{j}_w_goal", 1)
        P.add(f"o{j}_goal", 4)
        P.add(f"o{j}_w_reg", 1)
        P.add(f"o{j}_w_acc", 1)
        P.add(f"o{j}_w_aacc", 1)
        P.add(f"o{j}_w_pose", 1)
        P.add(f"o{j}_yaw_rel", 1)
        P.add(f"o{j}_w_offset", 1)
        P.add(f"o{j}_offset", 2)  # lateral and vertical offset from the base (base-yaw frame)
        # the top primitive it rests on (a static one, or one riding on a moving object)
        P.add(f"o{j}_sup_sel", st.n_obj + 1)
        P.add(f"o{j}_sup_pose", 12)
        P.add(f"o{j}_sup_loc", 5)
    for i in range(len(st.obj_pairs)):
        P.add(f"c{i}_sel", st.n_obj + 1)
        P.add(f"c{i}_pose", 12)  # static world primitive: centre (3) + R (9, column-major)
        P.add(f"c{i}_loc", 5)  # primitive in the moving object's frame: centre (3), cos, sin
        P.add(f"c{i}_half", 3)
        P.add(f"c{i}_w", 3)  # penalty weight, homotopy weight, surrogate exponent
    for i in range(st.env_pairs):
        P.add(f"e{i}_obj", st.n_obj)  # which moving object carries the point
        P.add(f"e{i}_pt", 4)  # point sphere in that object's frame: centre (3), radius
        P.add(f"e{i}_sel", st.n_obj + 1)
        P.add(f"e{i}_pose", 12)
        P.add(f"e{i}_loc", 5)
        P.add(f"e{i}_half", 3)
    return P


def _skew_cross(a, b):
    return ca.cross(a, b)


def _soft_norm(v, eps=1e-4):
    return ca.sqrt(ca.sumsqr(v) + eps * eps) - eps


def _primitive_frame(pp, tag: str, objs):
    """World frame (R, p) of a collision pair's primitive from its parameters ``<tag>_sel`` (static
    world primitive, or one riding on moving object j), ``<tag>_pose`` and ``<tag>_loc``."""
    sel, pose, loc = pp[f"{tag}_sel"], pp[f"{tag}_pose"], pp[f"{tag}_loc"]
    Rw = sel[0] * ca.reshape(pose[3:12], 3, 3)
    pw = sel[0] * pose[0:3]
    Rloc = rot_z_cs(loc[3], loc[4])
    for j, (pj, _, Rj) in enumerate(objs):
        Rw = Rw + sel[j + 1] * (Rj @ Rloc)
        pw = pw + sel[j + 1] * (pj + Rj @ loc[0:3])
    return Rw, pw


def box_sphere_distance(c_local, half, radius):
    """Signed distance sphere (centre in the box frame) to an axis-aligned box; smooth-ish."""
    q = ca.fabs(c_local) - half
    outside = _soft_norm(ca.fmax(q, 0))
    inside = ca.fmin(ca.fmax(ca.fmax(q[0], q[1]), q[2]), 0)
    return outside + inside - radius


def superellipsoid(c_local, half, radius, expo):
    """Surrogate geometry F(c) = sum |c_i/(a_i+r)|^p ; F >= 1 outside.  p=2 ellipsoid, p->inf box."""
    a = half + radius
    s = 0
    for i in range(3):
        s = s + ca.power((c_local[i] / a[i]) ** 2 + 1e-12, expo / 2)
    return s


class Window:
    """The symbolic knot window and its layouts (built once per :class:`Structure`)."""

    def __init__(self, model: G1Model, st: Structure):
        self.model = model
        self.st = st
        self.W = var_layout(st)
        self.P = par_layout(st)
        a = ca.SX.sym("a", self.W.n)
        b = ca.SX.sym("b", self.W.n)
        p = ca.SX.sym("p", self.P.n)
        self.a, self.b, self.p = a, b, p
        self._penalties: dict = {}
        g_blocks, f = self._build(a, b, p)
        self.G = Layout("g")
        exprs = []
        for name, e in g_blocks:
            self.G.add(name, e.numel())
            exprs.append(e)
        self.g = ca.vertcat(*exprs)
        self.collision_groups = self._collision_groups()
        #: the cost without the collision penalties (paper IV-C), which are in ``collision_groups``
        self.f_main = f
        self.f = f + sum((grp.penalty for grp in self.collision_groups), ca.SX(0))

    def _collision_penalty(self, group: str, weight, value, active) -> None:
        """A collision penalty ``weight * value`` of one pair, flat (zero value and derivatives)
        where ``active`` is 0."""
        cost, act = self._penalties.get(group, (ca.SX(0), ca.SX(0)))
        self._penalties[group] = (cost + weight * value, act + ca.fabs(weight) * active)

    def _collision_groups(self) -> list:
        rows: dict = {}
        for name, sl in self.G.blocks.items():
            m = _COLLISION_ROW.fullmatch(name)
            if m:
                rows.setdefault(m.group(1) or m.group(2) or m.group(3), []).extend(range(sl.start, sl.stop))
        groups = []
        for key in dict.fromkeys(list(rows) + list(self._penalties)):
            cost, act = self._penalties.get(key, (ca.SX(0), ca.SX(0)))
            groups.append(CollisionGroup(key, np.asarray(rows.get(key, []), np.int64), cost, act))
        return groups

    # ------------------------------------------------------------------------------------------
    def _build(self, a, b, p):
        m = self.model
        st = self.st
        M = st.n_obj
        wa = sx_split(self.W, a)
        wb = sx_split(self.W, b)
        pp = sx_split(self.P, p)
        dt = pp["dt"]
        mass = m.mass
        rows: list = []
        cost = 0

        def add(name, expr):
            rows.append((name, ca.vec(expr)))

        # ---- robot kinematics at knot k (a) and k+1 (b, only cheap parts used)
        tree = m.symbolic_tree(wa["x"], wa["xd"])
        com_x, h_x = m.com_and_momentum(tree)
        limbs = m.limb_frames(tree)
        spheres = m.sphere_centers(tree)
        tree_b = m.symbolic_tree(wb["x"], wb["xd"])
        limbs_b = m.limb_frames(tree_b)

        # ---- object poses (symbolic) at a and b
        def obj_state(w, j):
            pose = w[f"o{j}_pose"]
            return pose[0:3], pose[3:6], rpy_to_rot(pose[3:6])

        objs_a = [obj_state(wa, j) for j in range(M)]
        objs_b = [obj_state(wb, j) for j in range(M)]

        # ---- hands' contact frames: surface rotation (world, or the selected object's), normal, and
        # the point the force acts at (Options.hand_standoff below the hand point along the normal)
        def surface_rotation(h, objs):
            sel = pp[f"{h}_sel"]
            R = sel[0] * ca.SX.eye(3)
            for j in range(M):
                R = R + sel[j + 1] * objs[j][2]
            return R

        def force_point(h, p_hand, R_surface):
            return p_hand - st.hand_standoff * (R_surface @ pp[f"{h}_n"]) if st.hand_standoff > 0 else p_hand

        hand_R = {h: surface_rotation(h, objs_a) for h in HANDS}
        hand_n = {h: hand_R[h] @ pp[f"{h}_n"] for h in HANDS}
        hand_cp = {h: force_point(h, limbs[h][0], hand_R[h]) for h in HANDS}

        # ---- forces (robot scaled by m g)
        sole_pts = sole_force_points(st.cop_margin_front, st.cop_margin_side)
        feet_pts = {}
        forces = []  # (point, u) acting on the robot
        for f in FEET:
            u = ca.reshape(wa[f"u_{f}"], 3, 4)
            jid = m.limb_joint[f]
            pts = [tree["p"][jid] + tree["R"][jid] @ sole_pts[i] for i in range(4)]
            feet_pts[f] = pts
            for i in range(4):
                forces.append((pts[i], u[:, i]))
        for h in HANDS:
            forces.append((hand_cp[h], wa[f"u_{h}"]))
        sum_u = sum(u for _, u in forces)
        # limb joint torques (quasi-static: gravity of the distal links and the contact wrenches),
        # scaled by the joint's limit: the wrists (5 N m) failed the a-posteriori RNEA check
        # when the hands pushed or carried (see model.quasi_static_limb_torques)
        mg = mass * G
        wrenches = {f: ([(pt, mg * u) for pt, u in forces[4 * i:4 * i + 4]], 0) for i, f in enumerate(FEET)}
        wrenches.update({h: ([(hand_cp[h], mg * wa[f"u_{h}"])], mg * wa[f"tau_{h}"]) for h in HANDS})
        taus = m.quasi_static_limb_torques(tree, wrenches)
        # the waist also accelerates the torso, arms and head (model.inertial_torques)
        for group, inertial in m.inertial_torques(tree, tree_b, dt, st.inertial_groups).items():
            taus[group] = [ts + ti for ts, ti in zip(taus[group], inertial)]
        add("joint torques",
            ca.vertcat(*[taus[group][i] / m.tau_max[j - 2] for group, (js, _) in m.torque_row_joints.items()
                         for i, j in enumerate(js)]))
        torque = sum(ca.cross(pt - wa["com"], u) for pt, u in forces) + sum(wa[f"tau_{h}"] for h in HANDS)

        # ---- robot dynamics (window rows)
        add("kinematic integration", wb["x"] - wa["x"] - dt * wb["xd"])
        add("CoM integration", wb["com"] - wa["com"] - dt * wb["comd"])
        add("linear momentum dynamics", wb["comd"] - wa["comd"] - dt * G * (sum_u - ca.DM([0, 0, 1])))
        add("angular momentum dynamics", wb["kk"] - wa["kk"] - dt * G * torque)
        # rate of angular momentum about the CoM over the weight (m): the horizontal distance of the
        # centroidal moment pivot from the centre of pressure; bounded only when Options ask for it
        add("angular momentum rate (CMP offset)", torque[0:2])
        if st.interval_momentum:
            # the next interval's velocity at this knot's configuration, against its momentum at
            # the next knot (Options.interval_momentum_tolerance)
            _, h_ab = m.com_and_momentum(m.symbolic_tree(wa["x"], wb["xd"]))
            add("angular momentum across the interval", h_ab[3:6] / mass - wb["kk"])
        if st.upper_body_acceleration:
            # base rotation rates, waist and arm joints (Options.upper_body_acceleration_limit)
            add("upper-body acceleration", ca.vertcat(wb["xd"][3:6] - wa["xd"][3:6], wb["xd"][UPPER_BODY_XD] - wa["xd"][UPPER_BODY_XD]))
        # ---- centroidal consistency (knot rows)
        add("CoM consistency", wa["com"] - com_x)
        add("centroidal momentum consistency (CMM)",
            ca.vertcat(wa["comd"] - h_x[0:3] / mass, wa["kk"] - h_x[3:6] / mass))

        # ---- feet
        mu_f = pp["mu_foot"]
        for f in FEET:
            pt, R = limbs[f]
            pt_b, R_b = limbs_b[f]
            patch = pp[f"{f}_patch"]
            add(f"{f} on surface", pt[2] - pp[f"{f}_h"])
            add(f"{f} orientation aligned with surface", ca.vertcat(R[0, 2], R[1, 2]))
            dxy = pt[0:2] - patch[0:2]
            add(f"{f} inside contact patch",
                ca.vertcat(patch[2] * dxy[0] + patch[3] * dxy[1], -patch[3] * dxy[0] + patch[2] * dxy[1]))
            heading_a = R[0:2, 0]
            heading_b = R_b[0:2, 0]
            # xy, z, yaw; z is bounded only at lift-off (both knots' "on surface" rows cover it otherwise)
            add(f"{f} no slip", ca.vertcat(pt_b[0:3] - pt[0:3],
                                           heading_a[0] * heading_b[1] - heading_a[1] * heading_b[0]))
            u = ca.reshape(wa[f"u_{f}"], 3, 4)
            cones = []
            for i in range(4):
                cones += [mu_f * u[2, i] - u[0, i], mu_f * u[2, i] + u[0, i],
                          mu_f * u[2, i] - u[1, i], mu_f * u[2, i] + u[1, i]]
            add(f"{f} friction cone", ca.vertcat(*cones))
            # the CoM's ground point in the sole's frame (along, across): bounded in single stance
            # when Options ask for a support margin (the plan then never balances a step on momentum)
            dcom = wa["com"][0:2] - pt[0:2]
            add(f"{f} CoM over the sole", ca.vertcat(R[0, 0] * dcom[0] + R[1, 0] * dcom[1],
                                                     R[0, 1] * dcom[0] + R[1, 1] * dcom[1]))
            # swing foot height tracking (walking cost)
            cost += pp["w_stage"] * (1 - pp["b_st"]) * pp[f"{f}_w_swing"] * (pt[2] - pp[f"{f}_swing_h"]) ** 2

        # ---- hands
        mu_h = pp["mu_hand"]
        obj_forces = [[] for _ in range(M)]  # (point, force in robot-weight units) on object j
        obj_moments = [[] for _ in range(M)]  # pure moments (hand patches) on object j
        for h in HANDS:
            sel = pp[f"{h}_sel"]
            loc = pp[f"{h}_loc"]
            Rsel = hand_R[h]
            target = sel[0] * loc
            target_b = sel[0] * loc
            for j in range(M):
                pj, _, Rj = objs_a[j]
                target = target + sel[j + 1] * (pj + Rj @ loc)
                target_b = target_b + sel[j + 1] * (objs_b[j][0] + objs_b[j][2] @ loc)
            Rsel_b = surface_rotation(h, objs_b)
            pt = hand_cp[h]
            add(f"{h} contact position", pt - target)
            # on at release only: u_k acts over [t_k, t_k+1], so the hand still touches at k+1
            add(f"{h} release: still at the contact", force_point(h, limbs_b[h][0], Rsel_b) - target_b)
            n = hand_n[h]
            t1 = Rsel @ pp[f"{h}_t1"]
            t2 = Rsel @ pp[f"{h}_t2"]
            u = wa[f"u_{h}"]
            un = ca.dot(u, n)
            add(f"{h} friction cone", ca.vertcat(un, mu_h * un - ca.dot(u, t1), mu_h * un + ca.dot(u, t1),
                                                 mu_h * un - ca.dot(u, t2), mu_h * un + ca.dot(u, t2)))
            # patch contact (paper: hands as patches): the palm pressed on the face can exert a
            # moment, bounded like a rectangle's contact wrench: tilting moments keep the centre of
            # pressure inside the patch (|tau.t| <= half size * normal force), the moment about the
            # normal is bounded by torsional friction.  Without it two point grips cannot exert any
            # torque about the line between them (S2's carried box).  Named simplification: the
            # hand's orientation is not constrained to lie flat on the face (only to keep the
            # orientation it has when the contact begins, below); the bounds assume it flat.
            tau = wa[f"tau_{h}"]
            a = HAND_PATCH_HALF
            add(f"{h} patch moment", ca.vertcat(a * un - ca.dot(tau, t1), a * un + ca.dot(tau, t1),
                                                a * un - ca.dot(tau, t2), a * un + ca.dot(tau, t2),
                                                HAND_TORSION * un - ca.dot(tau, n), HAND_TORSION * un + ca.dot(tau, n)))
            # the grip sticks: the hand keeps its orientation on the surface from knot to knot (a
            # pressed patch neither rolls nor spins under friction). Without it S1's plans turned
            # the left hand 56 degrees against the box in the lift's first 0.1 s and 60-88 degrees
            # by the carry, while the box barely moved; no executed grasp held through it
            # (docs/to.md, session 22). Rows: the sine-vector, in the surface's frame, of the hand's
            # rotation there from knot a to b, times {h}_grip_axes (the axes it may not turn about:
            # all three on a face; on a bar it may roll about the bar, see grip_axes)
            E = Rsel_b.T @ limbs_b[h][1] @ limbs[h][1].T @ Rsel
            turn = 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])
            add(f"{h} grip: no rotation on the surface", ca.reshape(pp[f"{h}_grip_axes"], 3, 3) @ turn)
            for j in range(M):
                obj_forces[j].append((pt, -sel[j + 1] * u))
                obj_moments[j].append(-sel[j + 1] * tau)
            cost += pp[f"{h}_w_track"] * ca.sumsqr(pt - target)

        # ---- objects
        mu_o = pp["mu_obj"]
        for j in range(M):
            pa, rpya, Ra = objs_a[j]
            va = wa[f"o{j}_vel"]
            vb = wb[f"o{j}_vel"]
            pb = wb[f"o{j}_pose"]
            add(f"o{j} kinematic integration", pb - wa[f"o{j}_pose"] - dt * vb)
            mj = pp[f"o{j}_m"]
            us = ca.reshape(wa[f"o{j}_us"], 3, 4)
            corners = ca.reshape(pp[f"o{j}_corners"], 3, 4)
            cpts = [pa + Ra @ corners[:, i] for i in range(4)]
            allf = list(obj_forces[j]) + [(cpts[i], us[:, i]) for i in range(4)]
            F = sum(u for _, u in allf)
            T = sum(ca.cross(pt - pa, u) for pt, u in allf) + sum(obj_moments[j])
            # linear: (v_{k+1} - v_k) = dt (m_r g / m_j * F + g)
            add(f"o{j} linear dynamics", (vb[0:3] - va[0:3]) - dt * (mass * G / mj * F + ca.DM(GRAVITY)))
            Ib = ca.reshape(pp[f"o{j}_I"], 3, 3)
            Rb = rpy_to_rot(pb[3:6])
            wa_ = rpy_rate_matrix(rpya) @ va[3:6]
            wb_ = rpy_rate_matrix(pb[3:6]) @ vb[3:6]
            La = Ra @ (Ib @ (Ra.T @ wa_))
            Lb = Rb @ (Ib @ (Rb.T @ wb_))
            add(f"o{j} angular dynamics", (Lb - La) / mj - dt * mass * G / mj * T)
            add(f"o{j} support contact (on surface, aligned)", ca.vertcat(pa[2] - pp[f"o{j}_zrest"], rpya[0], rpya[1]))
            cones = []
            for i in range(4):
                cones += [mu_o * us[2, i] - us[0, i], mu_o * us[2, i] + us[0, i],
                          mu_o * us[2, i] - us[1, i], mu_o * us[2, i] + us[1, i]]
            add(f"o{j} support friction cone", ca.vertcat(*cones))
            # a carried object stays above the floor (its bottom corners): without it S1's plan
            # lifted the box with its lowest corner 14.5 cm below the floor at 3.2 s (roll 0.17 rad)
            add(f"o{j} above the floor", ca.vertcat(*[cpts[i][2] for i in range(4)]))
            heading = Ra[:, 0]
            lateral = Ra[:, 1]
            add(f"o{j} rolling: no longitudinal wheel force", ca.vertcat(*[ca.dot(us[:, i], heading) for i in range(4)]))
            # rolling resistance dissipates: a wheel's longitudinal force never points along the
            # wheel's velocity at the end of the interval (Coulomb, as the sim's wheel frictionloss;
            # at rest it holds either way).  Without it the bound +-f_rr let the floor drive the
            # trolley: the demo's plan sped it up from 0.24 to 0.34 m/s with no hand force, and the
            # executed trolley stopped 7 cm short of it (the robot fell, docs/execution.md session 8)
            add(f"o{j} rolling: resistance opposes motion",
                ca.vertcat(*[ROLLING_DISSIPATION_SCALE * ca.dot(us[:, i], heading)
                             * ca.dot(vb[0:3] + ca.cross(wb_, Ra @ corners[:, i]), heading) for i in range(4)]))
            axle_v = va[0:3] + ca.cross(wa_, Ra @ pp[f"o{j}_axle"])
            add(f"o{j} nonholonomic: no lateral slip", ca.dot(axle_v, lateral))
            att = pp[f"o{j}_att_sel"]
            off = pp[f"o{j}_att_off"]
            p_att = 0
            rpy_att = 0
            for i in range(M):
                if i == j:
                    continue
                pi_, rpyi, Ri = objs_a[i]
                p_att = p_att + att[i] * (pi_ + Ri @ off[0:3])
                rpy_att = rpy_att + att[i] * (rpyi + ca.vertcat(0, 0, off[3]))
            add(f"o{j} attachment", ca.vertcat(pa - p_att, rpya - rpy_att))
            # resting on another object's top, its centre stays over that top (bounds: the top's
            # half extents less a margin).  Without it S2's plan set the box down at deck height
            # with its footprint 1 cm over the trolley's edge, held by nothing (docs/to.md, session 28)
            Rs, ps = _primitive_frame(pp, f"o{j}_sup", objs_a)
            add(f"o{j} over its support", (Rs.T @ (pa - ps))[0:2])
            # ... and, where Options.placement_tolerance asks, it is set down at its goal
            add(f"o{j} at its placement goal", pa[0:2] - pp[f"o{j}_goal"][0:2])
            # object costs: placement goal and twist regulariser
            goal = pp[f"o{j}_goal"]
            cost += pp[f"o{j}_w_goal"] * (ca.sumsqr(pa - goal[0:3]) + 0.3 * (rpya[2] - goal[3]) ** 2)
            cost += pp["w_stage"] * pp[f"o{j}_w_reg"] * ca.sumsqr(va)
            # an object pushed over its support speeds up and slows down smoothly: a push the
            # hands keep up, not one kick and a coast (the demo's plan: 23.5 N for 0.1 s, then the
            # hands only rode along; executed, the trolley got 7 cm of its 25 and the robot fell)
            cost += pp["w_stage"] * pp[f"o{j}_w_acc"] * ca.sumsqr((vb[0:3] - va[0:3]) / dt)
            # a carried object turns smoothly too (its linear part is the row above)
            cost += pp["w_stage"] * pp[f"o{j}_w_aacc"] * ca.sumsqr((vb[3:6] - va[3:6]) / dt)
            # a carried object stays level and keeps its yaw relative to the base (the nominal's,
            # blended from the grasp to the placement): the way a person carries a box.  S1's task
            # file asks for it: with the fixed carry nominal its carry converged only with it
            # (docs/to.md, session 17; it does not stop the first lift knot's jerk)
            cost += pp["w_stage"] * pp[f"o{j}_w_pose"] * (
                rpya[0] ** 2 + rpya[1] ** 2 + 2 * (1 - ca.cos(rpya[2] - wa["x"][5] - pp[f"o{j}_yaw_rel"])))
            # ... and stays at the nominal's height and lateral offset from the base (the distance in
            # front is the solver's): no swing of the box across the body, no carry above the head
            cy, sy = ca.cos(wa["x"][5]), ca.sin(wa["x"][5])
            d = pa - wa["x"][0:3]
            cost += pp["w_stage"] * pp[f"o{j}_w_offset"] * ca.sumsqr(
                ca.vertcat(-sy * d[0] + cy * d[1], d[2]) - pp[f"o{j}_offset"])
            cost += pp["w_stage"] * pp["w_force"] * 0.1 * ca.sumsqr(wa[f"o{j}_us"])

        # ---- collisions: robot spheres vs object primitives
        for i, s_idx in enumerate(st.obj_pairs):
            sph = m.spheres[s_idx]
            c = spheres[s_idx]
            Rw, pw = _primitive_frame(pp, f"c{i}", objs_a)
            cl = Rw.T @ (c - pw)
            half = pp[f"c{i}_half"]
            wpen, whom, expo = pp[f"c{i}_w"][0], pp[f"c{i}_w"][1], pp[f"c{i}_w"][2]
            d = box_sphere_distance(cl, half, sph.radius)
            add(f"c{i} collision", d)
            Fs = superellipsoid(cl, half, sph.radius, expo)
            s = wa["slack"][i]
            add(f"c{i} homotopy surrogate", Fs - 1 + s)
            self._collision_penalty(f"c{i}", pp["w_stage"] * wpen, ca.fmin(d, 0) ** 2, d <= 0)
            self._collision_penalty(f"c{i}", pp["w_stage"] * whom, ca.fmax(1 - Fs, 0) ** 2, Fs <= 1)
            cost += pp["w_stage"] * whom * pp["w_slack"] * s ** 2
        # ---- a carried object's point spheres vs the other objects' primitives: hard rows in every
        # stage.  Without them S2's carry pulled the box off the table through its top edge (22 cm
        # down in 0.2 s) and the wrists followed it into the table (docs/to.md, session 27)
        for i in range(st.env_pairs):
            osel, pt = pp[f"e{i}_obj"], pp[f"e{i}_pt"]
            c = 0
            for j in range(M):
                pj, _, Rj = objs_a[j]
                c = c + osel[j] * (pj + Rj @ pt[0:3])
            Rw, pw = _primitive_frame(pp, f"e{i}", objs_a)
            add(f"e{i} carried object collision", box_sphere_distance(Rw.T @ (c - pw), pp[f"e{i}_half"], pt[3]))
        # every collision sphere above the floor (z = 0): the sole rows only keep the sole point
        # up, so a toe-down swing foot put its sphere 10 mm into the floor (push_trolley, t = 0.2 s)
        add("floor clearance", ca.vertcat(*[spheres[s][2] - m.spheres[s].radius for s in range(len(m.spheres))]))
        # the soles stay on their own side of the pelvis: left sole minus right sole along the base's
        # lateral axis. S1's plan walked with the left foot turned 1.7 rad and the ankles 25 cm crossed
        # (the sphere pairs are checked at knots only, so the knees passed through each other between
        # two of them, 68 mm deep on MuJoCo's meshes)
        lat = ca.vertcat(-ca.sin(wa["x"][5]), ca.cos(wa["x"][5]))
        add("feet apart", ca.dot(limbs["left_foot"][0][0:2] - limbs["right_foot"][0][0:2], lat))
        # the CoM inside a double stance's support, in the base's heading frame: the soles' centres
        # spread the support by half their offset each way (rear heel to front toe along, outer
        # edges across; exact for parallel soles). Bounded only when Options ask for a margin
        head = ca.vertcat(ca.cos(wa["x"][5]), ca.sin(wa["x"][5]))
        sole_l, sole_r = limbs["left_foot"][0][0:2], limbs["right_foot"][0][0:2]
        com_support = wa["com"]
        if st.load_in_support:   # the robot and the objects its hands carry
            held = [pp[f"o{j}_held"] * pp[f"o{j}_m"] for j in range(M)]
            com_support = (mass * wa["com"] + sum((hj * objs_a[j][0] for j, hj in enumerate(held)), ca.DM.zeros(3))) \
                / (mass + sum(held, 0))
        rel = com_support[0:2] - 0.5 * (sole_l + sole_r)
        half_al = 0.5 * _soft_norm(ca.dot(sole_l - sole_r, head))
        half_ac = 0.5 * _soft_norm(ca.dot(sole_l - sole_r, lat))
        add("CoM inside the double stance", ca.vertcat(ca.dot(rel, head) + half_al, ca.dot(rel, head) - half_al,
                                                       ca.dot(rel, lat) + half_ac, ca.dot(rel, lat) - half_ac))
        # deep hip flexion needs an abducted thigh, or the hip-roll link meets the pelvis (hip_coupling)
        add("hip roll coupling", hip_roll_clearance(wa["x"][6:]) - pp["hip_margin"])
        for (i, j) in st.self_pairs:
            si, sj = m.spheres[i], m.spheres[j]
            dd = ca.sumsqr(spheres[i] - spheres[j]) - (si.radius + sj.radius + pp["self_margin"]) ** 2
            add(f"self {i} {j}", dd)
            self._collision_penalty(f"self {i} {j}", pp["w_stage"] * pp["w_self"], ca.fmin(dd, 0) ** 2, dd <= 0)

        # ---- stage costs
        x, xd = wa["x"], wa["xd"]
        xr = pp["x_ref"]
        u_all = ca.vertcat(*[wa[f"u_{f}"] for f in FEET], *[wa[f"u_{h}"] for h in HANDS],
                           *[HAND_MOMENT_COST * wa[f"tau_{h}"] for h in HANDS])
        L_reg = (pp["w_post"] * ca.sumsqr(x[6:] - xr[6:]) + pp["w_xd"] * ca.sumsqr(xd[6:])
                 + 10 * pp["w_xd"] * ca.sumsqr(xd[0:6]) + pp["w_acc"] * ca.sumsqr(wb["xd"] - xd)
                 + pp["w_force"] * ca.sumsqr(u_all) + pp["w_upright"] * (x[3] ** 2 + x[4] ** 2)
                 # the soles' load changes smoothly: without it the demo push's plan threw the whole
                 # weight from one foot to the other and back every 0.2 s inside a double stance, and
                 # the executed robot fell off its unloaded foot (docs/execution.md, session 8)
                 + pp["w_force_rate"] * sum(ca.sumsqr(wb[f"u_{f}"] - wa[f"u_{f}"]) for f in FEET))
        mid = 0.5 * (limbs["left_foot"][0][0:2] + limbs["right_foot"][0][0:2])
        L_kff = pp["w_kff"] * ca.sumsqr(mid - pp["foot_des"])
        L_st = pp["w_st_com"] * ca.sumsqr(wa["com"][0:2] - mid) + pp["w_st_vel"] * ca.sumsqr(wa["comd"]) + L_kff
        L_wk = pp["w_wk_base"] * ca.sumsqr(x[0:2] - xr[0:2]) + pp["w_wk_base"] * (x[5] - xr[5]) ** 2
        cost += pp["w_stage"] * (pp["b_st"] * L_st + (1 - pp["b_st"]) * L_wk + L_reg)
        # keyframe base cost, eq. (1), and initial-state anchor
        xk = pp["x_kf"]
        cost += pp["w_kfb_z"] * (x[2] - xk[2]) ** 2 + pp["w_kfb_th"] * ca.sumsqr(x[6:] - xk[6:])
        cost += pp["w_anchor"] * ca.sumsqr(x - xr)
        return rows, cost


def rot_z_cs(c, s):
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
