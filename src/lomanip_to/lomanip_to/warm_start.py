"""A kinematically consistent stepping warm start for the knots of a TO problem.

Why: the keyframe nominal (``ProblemData._keyframe_nominal``) moves the base linearly between
anchors with a fixed posture, so in the warm start both feet slide along with the base: every
stance foot's no-slip row and every swing foot's height row is violated at the first iterate, and
ipopt spends most of its iterations discovering the footsteps (S1: 140-210 iterations per
subtask guide).  Here the contact schedule fixes a foothold per stance interval of each foot,
the swing foot follows a bump between footholds, held objects' contact points follow the objects'
nominal poses, the CoM is held over the feet (``com_targets``), and one small IK per knot (CasADi + ipopt,
warm-started from the previous knot) turns that into joint angles close to the nominal posture.

Footholds, in order of precedence: the interval holds knot 0 (the initial foot), a position given
in the schedule (``ContactSpec.position`` of a foot: the planner's footsteps), the interval holds a
keyframe knot (the keyframe's foot), else the nominal stance under the nominal base at the
interval's middle (+-0.119 m lateral, +0.035 m forward: the G1's standing stance).
Named simplification: the CoM target is a smoothed point between the feet, not a dynamic (ZMP)
plan; the TO then finds the dynamics.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .ik import SOLE_FORWARD, STANCE_HALF_WIDTH
from .model import FEET, HANDS, G1Model, rpy_to_rot
from .transcription import box_sphere_distance

#: weights of the per-knot tracking IK (metres and radians; posture terms are per joint)
W_FOOT, W_HAND, W_COM, W_POST, W_BASE_XY = 1e5, 1e3, 30.0, 1.0, 1.0
#: weight of the penetration penalty against fixed objects, and how many of their primitives
#: the IK takes (a nominal path through furniture, e.g. standing up at the S2 table, put the pelvis
#: 10 cm into the table top; the TO's guide stage then converged on the wrong side of it)
W_COLLISION, MAX_FIXED_PRIMS = 1e4, 16
#: sphere groups kept out of furniture in the warm start (hands and forearms may touch it)
BODY_GROUPS = ("pelvis", "torso", "head", "left_thigh", "right_thigh", "left_shin", "right_shin")
#: smoothing of the CoM target over time (s, Gaussian sigma)
COM_SMOOTHING = 0.15
#: fraction of the way from the mid-feet point to the support centre the CoM target moves
#: (0: the TO finds the lateral sway itself; see com_targets)
COM_SHIFT = 0.0

_CACHE: dict = {}


def _tracking_ik(model: G1Model, n_prims: int):
    """Per-knot least-squares IK: soles at (xyz, yaw) level, hand points, CoM xy, posture, body
    spheres out of ``n_prims`` fixed box primitives."""
    key = (id(model), n_prims)
    if key in _CACHE:
        return _CACHE[key]
    x = ca.SX.sym("x", 35)
    n_base = 35 + 8 + 6 + 2 + 2
    p = ca.SX.sym("p", n_base + 15 * n_prims)
    x_ref = p[0:35]
    feet = [p[35:39], p[39:43]]  # x, y, z, yaw
    hands = [p[43:46], p[46:49]]
    w_hand = p[49:51]
    com_xy = p[51:53]
    tree = model.symbolic_tree(x)
    com, _ = model.com_and_momentum(tree)
    lf = model.limb_frames(tree)
    cost = 0
    for i, f in enumerate(FEET):
        pt, R = lf[f]
        yaw = feet[i][3]
        cost += W_FOOT * (ca.sumsqr(pt - feet[i][0:3]) + R[0, 2] ** 2 + R[1, 2] ** 2
                          + (R[1, 0] * ca.cos(yaw) - R[0, 0] * ca.sin(yaw)) ** 2)
    for i, h in enumerate(HANDS):
        cost += W_HAND * w_hand[i] * ca.sumsqr(lf[h][0] - hands[i])
    cost += W_COM * ca.sumsqr(com[0:2] - com_xy)
    cost += W_POST * ca.sumsqr(x[6:] - x_ref[6:]) + W_BASE_XY * ca.sumsqr(x[0:2] - x_ref[0:2])
    cost += 5.0 * ca.sumsqr(x[3:5] - x_ref[3:5]) + 5.0 * (x[2] - x_ref[2]) ** 2
    centres = model.sphere_centers(tree)
    body = [i for i, sp in enumerate(model.spheres) if sp.group in BODY_GROUPS]
    for j in range(n_prims):
        q = p[n_base + 15 * j:n_base + 15 * (j + 1)]
        ctr, R, half = q[0:3], ca.reshape(q[3:12], 3, 3), q[12:15]
        for i in body:
            d = box_sphere_distance(R.T @ (centres[i] - ctr), half, model.spheres[i].radius)
            cost += W_COLLISION * ca.fmin(d, 0) ** 2
    s = ca.nlpsol("stepping_ik", "ipopt", {"x": x, "p": p, "f": cost}, {"print_time": False, "ipopt": {
        "print_level": 0, "sb": "yes", "max_iter": 100, "tol": 1e-6, "linear_solver": "mumps"}})
    _CACHE[key] = s
    return s


def _intervals(data, foot: str) -> list:
    """[(k0, k1, contact)] maximal runs of knots where ``foot`` touches the same surface."""
    K = data.grid.K
    out, k = [], 0
    while k < K:
        c = data.contact(k, foot)
        if c is None:
            k += 1
            continue
        k1 = k
        while k1 + 1 < K and data.contact(k1 + 1, foot) is not None and data.contact(k1 + 1, foot).object_id == c.object_id:
            k1 += 1
        out.append((k, k1, c))
        k = k1 + 1
    return out


def _foot_pose(model: G1Model, x: np.ndarray, foot: str) -> np.ndarray:
    pt, R = model.numeric(x)["limbs"][foot]
    return np.array([pt[0], pt[1], pt[2], math.atan2(R[1, 0], R[0, 0])])


def footholds(data, x_nom: np.ndarray) -> dict:
    """foot -> K x 4 (sole centre xyz, yaw) targets along the horizon (stance + swing)."""
    model, K, t = data.model, data.grid.K, data.grid.t
    out = {}
    kf_x = {k: kf.x() for k, kf in data.kf_knots.items()}
    for side, f in zip((1.0, -1.0), FEET):
        runs = _intervals(data, f)
        holds = []
        for k0, k1, c in runs:
            h = data._surface_height(c)
            if k0 == 0:
                pose = _foot_pose(model, data.x_init, f)
            elif c.position is not None and len(c.position) >= 2:
                yaw = float(x_nom[(k0 + k1) // 2, 5])
                pose = np.array([c.position[0], c.position[1], h, yaw])
            else:
                kk = [k for k in kf_x if k0 <= k <= k1]
                if kk:
                    pose = _foot_pose(model, kf_x[kk[0]], f)
                else:
                    xb = x_nom[(k0 + k1) // 2]
                    yaw = float(xb[5])
                    fwd, lat = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
                    xy = xb[:2] + SOLE_FORWARD * fwd + side * STANCE_HALF_WIDTH * lat
                    pose = np.array([xy[0], xy[1], h, yaw])
            pose[2] = h
            holds.append((k0, k1, pose))
        P = np.zeros((K, 4))
        if not holds:  # never in contact: keep the nominal feet
            for k in range(K):
                P[k] = _foot_pose(model, x_nom[k], f)
            out[f] = P
            continue
        swings_first = holds[0][0] > 0
        if swings_first:
            # the foot swings from knot 0 on (a segment that starts with a step): it leaves from where
            # it is, not from its first foothold (which put it on the box top 0.1 s into S1's last
            # subtask, 0.43 m ahead and 0.3 m up)
            holds.insert(0, (0, 0, _foot_pose(model, data.x_init, f)))
        for i, (k0, k1, pose) in enumerate(holds):
            P[k0:k1 + 1] = pose
            nxt = holds[i + 1] if i + 1 < len(holds) else None
            if nxt is None:
                P[k1 + 1:] = pose
                continue
            ka, kb, pb = k1, nxt[0], nxt[2]
            if not (i == 0 and swings_first):  # a lift-off knot is still planted (the no-slip rows)
                ka = min(k1 + 1, kb - 1)
                P[ka] = pose
            for k in range(ka + 1, kb):
                s = (t[k] - t[ka]) / max(t[kb] - t[ka], 1e-9)
                q = pose + s * (pb - pose)
                q[3] = pose[3] + s * math.remainder(pb[3] - pose[3], 2 * math.pi)
                q[2] = data._swing_height(k, f)
                P[k] = q
        out[f] = P
    return out


#: the knots this long (s) before a hand's touch aim the hand at a point APPROACH_OFFSET (m) outside
#: the contact along its normal, with weight APPROACH_WEIGHT (contact knots: 1)
APPROACH_TIME, APPROACH_OFFSET, APPROACH_WEIGHT = 0.4, 0.10, 0.3


def _approach(data, h: str, k: int):
    """(point, weight) of a hand with no contact at knot ``k`` that touches an object within
    APPROACH_TIME, else None.

    Why: without a target the hand follows the joint-space blend to the keyframe's arm posture; in a
    graph plan of S1 that took the right hand under the shelf board and through it between two knots
    on its way to the basket, and the hard hand-vs-basket row at the knot before the touch could then
    not be met (docs/to.md, session 5)."""
    t = data.grid.t
    for kk in range(k + 1, data.grid.K):
        if t[kk] - t[k] > APPROACH_TIME + 1e-9:
            return None
        c = data.contact(kk, h)
        if c is None:
            continue
        if c.position is None or c.normal is None:
            return None
        return np.asarray(c.position, float) + APPROACH_OFFSET * _unit_normal(c), APPROACH_WEIGHT
    return None


def _unit_normal(c) -> np.ndarray:
    n = np.asarray(c.normal, float)
    return n / max(np.linalg.norm(n), 1e-9)


def hand_targets(data) -> dict:
    """hand -> (K x 3 points, K weights): contact points following the objects' nominal poses, and
    a point outside the contact for the knots just before a touch (``_approach``)."""
    K = data.grid.K
    out = {}
    for h in HANDS:
        P, w = np.zeros((K, 3)), np.zeros(K)
        for k in range(K):
            c = data.contact(k, h)
            if c is None:
                a = _approach(data, h, k) if k > 0 else None
                if a is not None:
                    P[k], w[k] = a
                continue
            k0 = k
            while k0 > 0 and data.contact(k0 - 1, h) is not None and data.contact(k0 - 1, h).object_id == c.object_id:
                k0 -= 1
            c0 = data.contact(k0, h)
            pos = np.asarray(c0.position, float)
            n = np.zeros(3) if c0.normal is None else _unit_normal(c0)
            if c.object_id in data.obj_nom:
                a, b = data.obj_nom[c.object_id][k0], data.obj_nom[c.object_id][k]
                Rab = rpy_to_rot(b[3:]) @ rpy_to_rot(a[3:]).T
                pos, n = b[:3] + Rab @ (pos - a[:3]), Rab @ n
            # the hand point stands off the surface (Options.hand_standoff)
            P[k], w[k] = pos + data.prob.options.hand_standoff * n, 1.0
        out[h] = (P, w)
    return out


def com_targets(data, feet: dict) -> np.ndarray:
    """K x 2: the mid-feet point moved ``COM_SHIFT`` of the way to the support centre, smoothed.

    A full shift over the stance foot (static walking) changed the TO's step into one the
    whole-body controller tracks worse (case_one_step pelvis error under physics: 4.1 cm with
    shift 1, 4.3 cm with 0.5, 3.4 cm with 0; 3.2 cm from the old sliding warm start)."""
    K, t = data.grid.K, data.grid.t
    raw = np.zeros((K, 2))
    for k in range(K):
        mid = 0.5 * (feet[FEET[0]][k, :2] + feet[FEET[1]][k, :2])
        sup = [feet[f][k, :2] for f in FEET if data.contact(k, f) is not None]
        raw[k] = mid + COM_SHIFT * (np.mean(sup, axis=0) - mid) if sup else mid
    out = np.zeros_like(raw)
    for k in range(K):
        wts = np.exp(-0.5 * ((t - t[k]) / COM_SMOOTHING) ** 2)
        out[k] = wts @ raw / wts.sum()
    return out


def fixed_primitives(data, x_nom: np.ndarray) -> np.ndarray:
    """IK parameters (centre, R column-major, half extents) of the fixed objects' primitives that
    come within 0.5 m of the nominal base path (at most ``MAX_FIXED_PRIMS``, nearest first)."""
    from .discretize import obj_prims_world

    base = np.asarray(x_nom, float)[:, :3]
    prims = [pr for o in data.prob.objects if o.id not in data.midx for pr in obj_prims_world(o)]
    scored = []
    for c, R, he in prims:
        q = np.abs((base - c) @ R) - he
        dist = float(np.min(np.linalg.norm(np.maximum(q, 0), axis=1)))
        if dist < 0.5:
            scored.append((dist, np.concatenate([c, np.asarray(R).ravel(order="F"), he])))
    scored.sort(key=lambda s: s[0])
    return np.concatenate([v for _, v in scored[:MAX_FIXED_PRIMS]]) if scored else np.zeros(0)


def stepping_guess(data, x_nom: np.ndarray) -> np.ndarray:
    """K x 35 configurations: ``x_nom``'s base path and posture, with the feet on footholds."""
    model, K = data.model, data.grid.K
    feet = footholds(data, x_nom)
    hands = hand_targets(data)
    com = com_targets(data, feet)
    prims = fixed_primitives(data, x_nom)
    ik = _tracking_ik(model, len(prims) // 15)
    # the TO's joint bounds (hip yaw in its gait range, the waist yaw in Options.waist_yaw_range)
    q_lo, q_hi = model.gait_q_bounds(data.prob.options.waist_yaw_range, data.x_init[6:])
    lbx = np.concatenate([np.full(3, -np.inf), [-0.6, -0.6, -np.inf], q_lo])
    ubx = np.concatenate([np.full(3, np.inf), [0.6, 0.6, np.inf], q_hi])
    X = np.array(x_nom, float)
    X[0] = data.x_init
    prev = X[0].copy()
    for k in range(1, K):
        p = np.concatenate([x_nom[k], feet[FEET[0]][k], feet[FEET[1]][k], hands[HANDS[0]][0][k],
                            hands[HANDS[1]][0][k], [hands[HANDS[0]][1][k], hands[HANDS[1]][1][k]], com[k], prims])
        x0 = np.clip(prev, lbx, ubx)
        x0[5] = x_nom[k, 5]
        sol = ik(x0=x0, p=p, lbx=lbx, ubx=ubx)
        xk = np.array(sol["x"]).ravel()
        if np.all(np.isfinite(xk)):
            X[k] = xk
            prev = xk
    return X
