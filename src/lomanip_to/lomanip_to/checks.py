"""Physical consistency checks of a TO result (reusable by tests, the benchmark and the node).

Each check returns a float (worst value, SI units) plus where it happens; ``run_checks`` collects
them with pass/fail against tolerances.  Penetration is the measure of DESIGN.md sec. 7: at each
time the sum of negative signed distances between robot collision bodies (spheres, see
``model.py``) and the objects / floor, plus robot self-collision pairs and the depth of a carried
object in another object; intended contacts (a hand on the object it holds, a foot on the surface it
stands on) are excluded.
"""

from __future__ import annotations

import numpy as np

from .hip_coupling import HIP_JOINTS, hip_roll_clearance
from .model import FEET, GRAVITY, HANDS, G1Model, quat_xyzw_to_rot, rpy_rate_matrix, rpy_to_rot

TOL = {
    "friction_cone": 1e-3,  # N (after scaling), cone rows
    "momentum_rate": 1e-2,  # N or N m
    "foot_slip": 2e-3,  # m between consecutive stance knots
    "penetration": 5e-3,  # m
    "joint_limits": 1e-4,  # rad
    "torque_ratio": 1.0,  # |tau| / tau_max
    "placement": 0.05,  # m, object position at its placement goal's time
    "placement_yaw": 0.15,  # rad
    "momentum_between_knots": 1.0,  # kg m^2/s, see momentum_between_knots
    "hand_grip_rotation": 0.02,  # rad, see hand_grip_rotation
}


def sphere_box_distance(c, centre, R, half, r):
    loc = R.T @ (np.asarray(c) - centre)
    q = np.abs(loc) - half
    return float(np.linalg.norm(np.maximum(q, 0)) + min(q.max(), 0.0) - r)


def _face_grid(half: np.ndarray, n: int = 7) -> np.ndarray:
    """(m, 3) points on the six faces of a box (n x n per face), in its frame."""
    u = np.linspace(-1.0, 1.0, n)
    a, b = np.meshgrid(u, u)
    a, b = a.ravel(), b.ravel()
    out = []
    for ax in range(3):
        o1, o2 = [i for i in range(3) if i != ax]
        for sgn in (-1.0, 1.0):
            f = np.zeros((a.size, 3))
            f[:, ax], f[:, o1], f[:, o2] = sgn, a, b
            out.append(f * half)
    return np.concatenate(out)


def carried_object_depths(data, res, k: int) -> list:
    """Depths (m) at knot ``k`` of the faces of each object carried free (off every support) in
    the other objects' primitives: a box through a table is not physics, whoever holds it.  Faces
    are sampled 7 x 7, so an edge of the other object between samples is missed by at most a few mm."""
    from .discretize import box_distances, obj_prims_world

    out = []
    for oid, poses in res.object_pose_knots.items():
        if data.obj_mode(k, oid) != "free":
            continue
        o = data.prob.object(oid)
        pts = []
        for (c, R, he) in obj_prims_world(o, poses[k][:3], poses[k][3:]):
            pts.append(c + _face_grid(he) @ R.T)
        pts = np.concatenate(pts)
        for other in data.prob.objects:
            if other.id == oid:
                continue
            op = res.object_pose_knots.get(other.id)
            prims = obj_prims_world(other, op[k][:3], op[k][3:]) if op is not None else obj_prims_world(other)
            for prim in prims:
                d = float(box_distances(pts, *prim, 0.0).min())
                if d < 0:
                    out.append(-d)
    return out


def penetration_per_knot(model: G1Model, data, res):
    """(sum of penetrations per knot (K,), max single penetration, its knot)."""
    from .discretize import obj_prims_world, self_pairs

    K = len(res.t_knots)
    total = np.zeros(K)
    worst, worst_k = 0.0, 0
    sp = self_pairs(model, data.prob.options.hand_body_self_pairs, data.prob.options.arm_body_self_pairs)
    for k in range(K):
        cs = model.numeric(res.x_knots[k])["spheres"]
        depth = []
        for o in data.prob.objects:
            if o.id in res.object_pose_knots:
                pose = res.object_pose_knots[o.id][k]
                prims = obj_prims_world(o, pose[:3], pose[3:])
            else:
                prims = obj_prims_world(o)
            for s_idx, s in enumerate(model.spheres):
                if not data._pair_enabled(k, s_idx, o.id):
                    continue
                allowed = max(-data._clearance(s_idx, k, o.id), 0.0)  # a held object's forearm allowance
                for (c, R, he) in prims:
                    d = sphere_box_distance(cs[s_idx], c, R, he, s.radius) + allowed
                    if d < 0:
                        depth.append(-d)
        for s_idx, s in enumerate(model.spheres):
            d = cs[s_idx][2] - s.radius  # floor
            if d < 0:
                depth.append(-d)
        for o in data.prob.objects:   # a moving object's bottom corners against the floor
            if o.id not in res.object_pose_knots:
                continue
            pose = res.object_pose_knots[o.id][k]
            z = pose[2] + o.bottom_corners() @ rpy_to_rot(pose[3:6])[2]
            depth.extend((-z[z < 0]).tolist())
        for (i, j) in sp:
            d = np.linalg.norm(cs[i] - cs[j]) - model.spheres[i].radius - model.spheres[j].radius
            if d < 0:
                depth.append(-d)
        depth.extend(carried_object_depths(data, res, k))
        total[k] = float(np.sum(depth)) if depth else 0.0
        mx = max(depth) if depth else 0.0
        if mx > worst:
            worst, worst_k = mx, k
    return total, worst, worst_k


def friction_cone_violation(res, mu_foot=0.6, mu_hand=0.8):
    """Worst violation (N) of the (exact, circular) friction cones; uses the contact normals."""
    worst, where = 0.0, ("", 0.0)
    for f in FEET:
        C = res.corner_forces_knots[f]
        for k in range(C.shape[0]):
            for i in range(4):
                fx, fy, fz = C[k, i]
                v = max(-fz, np.hypot(fx, fy) - mu_foot * fz)
                if v > worst:
                    worst, where = v, (f, res.t_knots[k])
    for h in HANDS:
        F = res.forces_knots[h]
        N = res.normals_knots[h]
        for k in range(F.shape[0]):
            if not np.any(F[k]):
                continue
            fn = float(F[k] @ N[k])
            ft = np.linalg.norm(F[k] - fn * N[k])
            v = max(-fn, ft - mu_hand * fn)
            if v > worst:
                worst, where = v, (h, res.t_knots[k])
    return worst, where


def momentum_rate_residual(model: G1Model, res):
    """max over knots of |(h_{k+1}-h_k)/dt - (sum f_k + m g ; sum (p - c) x f_k + tau_k)| (N, N m).

    Uses the knot centroidal momentum recomputed from (x, xd) with the model (not the solver's
    own variables), so it checks the CMM consistency and Newton-Euler together."""
    t = res.t_knots
    K = len(t)
    h = np.array([model.numeric(res.x_knots[k], res.xd_knots[k])["h"] for k in range(K)])
    com = np.array([model.numeric(res.x_knots[k])["com"] for k in range(K)])
    worst, wk = 0.0, 0
    for k in range(K - 1):
        dt = t[k + 1] - t[k]
        F = model.mass * GRAVITY.copy()
        T = np.zeros(3)
        for limb in res.limbs:
            F = F + res.forces_knots[limb][k]
            T = T + np.cross(res.points_knots[limb][k] - com[k], res.forces_knots[limb][k]) + res.torques_knots[limb][k]
        r = np.concatenate([(h[k + 1, :3] - h[k, :3]) / dt - F, (h[k + 1, 3:] - h[k, 3:]) / dt - T])
        v = float(np.abs(r).max())
        if v > worst:
            worst, wk = v, k
    return worst, float(t[wk])


def penetration_between_knots(model: G1Model, data, res, rate: float = 50.0):
    """(max penetration m, t) of the robot's spheres into the objects on the dense grid between
    knots (``TOResult.densify``), for the pairs the TO keeps apart at both neighbouring knots.

    Why: the collision rows hold at knots only. S1's plans held the box against the torso, head and
    upper arms at every knot (clearance 0) and passed up to 15 cm through them in between."""
    import copy

    from .discretize import obj_prims_world
    from .model import rot_to_rpy

    dense = copy.copy(res).densify(rate)
    tk = res.t_knots
    radii = np.array([sph.radius for sph in model.spheres])
    enabled = {}  # (knot, object id) -> mask over the spheres

    def on(k, oid):
        if (k, oid) not in enabled:
            enabled[k, oid] = np.array([data._pair_enabled(k, i, oid) for i in range(len(radii))])
        return enabled[k, oid]

    allowance = {}

    def allowed(k, oid):  # a held object's forearm allowance (Options.forearm_clear_of_held_object)
        if (k, oid) not in allowance:
            allowance[k, oid] = np.array([max(-data._clearance(i, k, oid), 0.0) for i in range(len(radii))])
        return allowance[k, oid]

    worst, where = 0.0, 0.0
    for i, t in enumerate(dense.t):
        k = int(np.searchsorted(tk, t, side="right")) - 1
        if k >= len(tk) - 1 or np.min(np.abs(tk - t)) < 1e-6:
            continue  # at a knot: penetration_per_knot's business
        x = np.concatenate([dense.base_position[i], rot_to_rpy(quat_xyzw_to_rot(dense.base_quat_xyzw[i])),
                            dense.joint_positions[i]])
        cs = np.asarray(model.numeric(x)["spheres"])
        for o in data.prob.objects:
            if o.id in dense.object_positions:
                prims = obj_prims_world(o, dense.object_positions[o.id][i],
                                        rot_to_rpy(quat_xyzw_to_rot(dense.object_quat_xyzw[o.id][i])))
            else:
                prims = obj_prims_world(o)
            mask = on(k, o.id) & on(k + 1, o.id)
            for (c, R, he) in prims:
                q = np.abs((cs - c) @ R) - he  # per sphere, in the primitive's frame
                d = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0) - radii
                d = np.where(mask, -d - np.minimum(allowed(k, o.id), allowed(k + 1, o.id)), 0.0)
                j = int(np.argmax(d))
                if d[j] > worst:
                    worst, where = float(d[j]), float(t)
    return worst, where


def momentum_between_knots(model: G1Model, res, rate: float = 100.0):
    """max over the dense grid of |L_dense - L_plan| (kg m^2/s): the centroidal angular momentum of
    the densified motion (the C1 interpolant a controller tracks, ``TOResult.densify``) from
    Pinocchio, against the plan's own angular momentum interpolated between its knots.

    Why: the TO's dynamics hold at knots 0.1-0.2 s apart.  S1 plans that passed every knot check
    swung arms and waist at up to 10 rad/s between knots; their densified motion carried 3-5 kg m^2/s
    the plan did not (the pushes that execute: 0.5-0.6), and no controller could balance it."""
    import copy

    import pinocchio as pin

    dense = copy.copy(res).densify(rate)
    m, d = model.pin_model, model.pin_data
    worst, where = 0.0, 0.0
    for i in range(len(dense.t)):
        q = np.concatenate([dense.base_position[i], dense.base_quat_xyzw[i], dense.joint_positions[i]])
        R = quat_xyzw_to_rot(dense.base_quat_xyzw[i])
        v = np.concatenate([R.T @ dense.base_linear_velocity[i], R.T @ dense.base_angular_velocity[i],
                            dense.joint_velocities[i]])
        pin.computeCentroidalMomentum(m, d, q, v)
        dev = float(np.linalg.norm(np.asarray(d.hg.angular) - dense.angular_momentum[i]))
        if dev > worst:
            worst, where = dev, float(dense.t[i])
    return worst, where


def foot_slip(res):
    """Max displacement (m) of a foot sole centre over an interval whose start knot carries its force.

    Forces are explicit (u_k acts over [t_k, t_k+1]), so a foot in contact at knot k must still be at
    the same place at k+1, also when k+1 is the first swing knot (lift-off).
    """
    worst, where = 0.0, ("", 0.0)
    for f in FEET:
        P = res.points_knots[f]
        obj = res.contact_objects_knots[f]
        for k in range(len(obj) - 1):
            if obj[k] and (obj[k] == obj[k + 1] or not obj[k + 1]):
                d = float(np.linalg.norm(P[k + 1] - P[k]))
                if d > worst:
                    worst, where = d, (f, res.t_knots[k])
    return worst, where


def hand_grip_rotation(model: G1Model, res):
    """Max angle (rad) a hand turns on the surface it holds, from the contact's first knot.

    A pressed patch sticks: the hand's orientation in the frame of the object it touches (the world
    for a fixed surface) stays what it was when the contact began; on a bar it may roll about the
    bar (``transcription.grip_axes``).
    """
    import pinocchio as pin

    from .transcription import grip_axes

    worst, where = 0.0, ("", 0.0)
    normals = getattr(res, "normals_knots", None) or {}
    limbs = {}  # knot -> limb frames, evaluated once for both hands
    for h in HANDS:
        obj = res.contact_objects_knots[h]
        ref = None
        for k in range(len(obj)):
            if not obj[k]:
                ref = None
                continue
            if k not in limbs:
                limbs[k] = model.numeric(res.x_knots[k])["limbs"]
            pose = res.object_pose_knots.get(obj[k])
            R_obj = rpy_to_rot(pose[k, 3:6]) if pose is not None else np.eye(3)
            R_rel = R_obj.T @ limbs[k][h][1]
            if ref is None or obj[k] != obj[k - 1]:
                ref = R_rel
                n = normals[h][k] if h in normals else np.zeros(3)
                held = grip_axes(R_obj.T @ n) if np.any(n) else np.eye(3)
            # the turn from the first knot's grip to this one, as a rotation vector in the object's frame
            ang = float(np.linalg.norm(held @ pin.log3(R_rel @ ref.T)))
            if ang > worst:
                worst, where = ang, (h, res.t_knots[k])
    return worst, where


def joint_limit_violation(model: G1Model, res):
    """Worst excess over the joint ranges and over the coupled hip limit (after the start knot)."""
    th = res.x_knots[:, 6:]
    v = np.maximum(model.q_lower - th, th - model.q_upper)
    k, j = np.unravel_index(np.argmax(v), v.shape)
    worst = (float(max(v.max(), 0.0)), (model.joint_names[j], float(res.t_knots[k])))
    if len(th) > 1:
        c = -hip_roll_clearance(th[1:].T).T  # (knots, sides)
        kc, s = np.unravel_index(np.argmax(c), c.shape)
        if c[kc, s] > worst[0]:
            worst = (float(c[kc, s]), (f"{tuple(HIP_JOINTS)[s]} hip roll coupling", float(res.t_knots[kc + 1])))
    return worst


def torque_ratio(model: G1Model, res):
    """max |tau_j| / tau_max_j over the knots: every joint's torque from the Newton-Euler of the
    links it carries (gravity, the contact wrenches on them, and the rate of their momentum between
    knots k and k+1), in the discretisation of the TO's dynamics rows (forces at k act over
    [t_k, t_k+1]; ``momentum_rate_residual`` uses the same).  ``G1Model.inertial_torques`` is tested
    against Pinocchio's RNEA.

    Why not RNEA with a central-difference acceleration (the check before session 12): it mixed the
    acceleration of the interval before a knot with the forces of the interval after it, so its
    floating base was out of balance by up to 330 N on S1's plans (1.5-30 N on pushes), and that
    imbalance showed up as joint torque.  Also returns the worst joint, its time, and as a cross-check
    the largest ratio and base-wrench residual of Pinocchio's RNEA with the forward-difference
    acceleration."""
    t = res.t_knots
    K = len(t)
    groups = tuple(model.torque_row_joints)
    worst, where = 0.0, ("", 0.0)
    rnea_worst, base_res = 0.0, 0.0
    trees = [model.symbolic_tree(res.x_knots[k], res.xd_knots[k]) for k in range(K)]
    for k in range(K):
        wrenches = {limb: ([(res.points_knots[limb][k], res.forces_knots[limb][k])], res.torques_knots[limb][k])
                    for limb in res.limbs}
        taus = model.quasi_static_limb_torques(trees[k], wrenches)
        if k < K - 1:
            for g, extra in model.inertial_torques(trees[k], trees[k + 1], t[k + 1] - t[k], groups).items():
                taus[g] = [a + b for a, b in zip(taus[g], extra)]
            xdd = (res.xd_knots[k + 1] - res.xd_knots[k]) / (t[k + 1] - t[k])
        else:  # the last knot is at rest
            xdd = np.zeros(35)
        for g, (joints, _) in model.torque_row_joints.items():
            for pid, tau in zip(joints, taus[g]):
                r = abs(float(tau)) / model.tau_max[pid - 2]
                if r > worst:
                    worst, where = r, (model.joint_names[pid - 2], float(t[k]))
        tau_rnea, base = _rnea_with_moments(model, res, k, xdd)
        rnea_worst = max(rnea_worst, float(np.max(np.abs(tau_rnea) / model.tau_max)))
        base_res = max(base_res, float(np.abs(base).max()))
    return worst, where, base_res, rnea_worst


def torque_ratio_between_knots(model: G1Model, res, rate: float = 100.0):
    """max |tau_j| / tau_max_j on the dense grid a controller tracks: Pinocchio's RNEA on the
    interpolation of ``TOResult.densify`` (positions, velocities, and the velocities' derivative as
    acceleration), each knot's contact wrenches held over its interval at the contact point
    carried with its limb.  Returns (ratio, (joint, t)).

    Why: ``torque_ratio`` sees the knots and the TO's forward-difference acceleration only.
    Between knots the tracked motion may ask for far more: a converged S1 prefix (session 23's RP)
    passes the knot check at 0.82 of the limits, and its dense plan needs 2.5 times the waist
    pitch's limit at 4.69 s (the demo push: 0.72 at the knots and between them).
    """
    import types

    import pinocchio as pin

    from .result import _contact_sides, _hermite

    tk = res.t_knots
    K = len(tk)
    if K < 2:
        return 0.0, ("", 0.0)
    t = tk[0] + np.arange(int(np.floor((tk[-1] - tk[0]) * rate + 1e-9)) + 1) / rate
    X, Xd = _hermite(tk, res.x_knots, t, _contact_sides(res.contact_objects_knots))
    Xdd = np.gradient(Xd, t, axis=0)
    idx = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, K - 1)
    m, d = model.pin_model, model.pin_data

    def limb_frames(x):
        pin.forwardKinematics(m, d, model.x_to_q(x))
        return {limb: d.oMi[model.limb_joint[limb]] for limb in res.limbs}

    local = {limb: np.zeros((K, 3)) for limb in res.limbs}  # contact point in the limb's joint frame
    for k in range(K):
        for limb, oMi in limb_frames(res.x_knots[k]).items():
            local[limb][k] = oMi.rotation.T @ (res.points_knots[limb][k] - oMi.translation)
    points = {limb: np.zeros((len(t), 3)) for limb in res.limbs}  # carried with the limb
    for i in range(len(t)):
        for limb, oMi in limb_frames(X[i]).items():
            points[limb][i] = oMi.translation + oMi.rotation @ local[limb][idx[i]]
    dense = types.SimpleNamespace(limbs=res.limbs, x_knots=X, xd_knots=Xd, points_knots=points,
                                  forces_knots={limb: f[idx] for limb, f in res.forces_knots.items()},
                                  torques_knots={limb: f[idx] for limb, f in res.torques_knots.items()})
    worst, where = 0.0, ("", 0.0)
    for i in range(len(t)):
        r = np.abs(_rnea_with_moments(model, dense, i, Xdd[i])[0]) / model.tau_max
        j = int(np.argmax(r))
        if r[j] > worst:
            worst, where = float(r[j]), (model.joint_names[j], float(t[i]))
    return worst, where


def _rnea_with_moments(model: G1Model, res, k, xdd):
    import pinocchio as pin

    m, d = model.pin_model, model.pin_data
    x, xd = res.x_knots[k], res.xd_knots[k]
    q = model.x_to_q(x)
    v = model.xd_to_v(x, xd)
    eps = 1e-6
    a = (model.xd_to_v(x + eps * xd, xd + eps * xdd) - v) / eps
    pin.forwardKinematics(m, d, q)
    fext = [pin.Force.Zero() for _ in range(m.njoints)]
    for limb in res.limbs:
        j = model.limb_joint[limb]
        oMi = d.oMi[j]
        Rt = oMi.rotation.T
        f_w = res.forces_knots[limb][k]
        tau_w = res.torques_knots[limb][k] + np.cross(res.points_knots[limb][k] - oMi.translation, f_w)
        fext[j] = fext[j] + pin.Force(Rt @ f_w, Rt @ tau_w)
    tau = pin.rnea(m, d, q, v, a, fext)
    return np.array(tau[6:]), np.array(tau[:6])


def held_object_forearm_depth(model: G1Model, data, res):
    """(deepest, "sphere vs object t=...") a forearm sphere reaches, at the knots, into an object its own
    hand touches.  Reported, not gated: those pairs have no rows unless
    Options.forearm_clear_of_held_object, and every plan before it carried its box with the wrist
    links 3-8 cm inside it on MuJoCo's meshes (docs/execution.md, session 40)."""
    from .discretize import obj_prims_world

    objects = {o.id: o for o in data.prob.objects}
    worst, where = 0.0, ""
    for k in range(len(res.t_knots)):
        cs = None
        for side in ("left", "right"):
            c = data.contact(k, f"{side}_hand")
            if c is None or c.object_id not in objects:
                continue
            o = objects[c.object_id]
            if o.id in res.object_pose_knots:
                pose = res.object_pose_knots[o.id][k]
                prims = obj_prims_world(o, pose[:3], pose[3:])
            else:
                prims = obj_prims_world(o)
            if cs is None:
                cs = model.numeric(res.x_knots[k])["spheres"]
            for i, sph in enumerate(model.spheres):
                if sph.group != f"{side}_forearm":
                    continue
                d = min(sphere_box_distance(cs[i], cc, R, he, sph.radius) for (cc, R, he) in prims)
                if -d > worst:
                    worst, where = float(-d), f"{sph.name} vs {o.id} t={float(res.t_knots[k]):.2f}"
    return worst, where


def placement_error(data, res) -> tuple:
    """Worst (position error m, yaw error rad, object id, t) over the placement goals, at each goal's
    time (the end when it has none).

    Why: the goals are costs, not rows, so a converged solve may leave an object short of its goal.
    Every S2 plan and every demo push passed all the physical checks with the trolley never moved
    (0.5 m and 0.25 m short)."""
    worst = (0.0, 0.0, "", 0.0)
    t = res.t_knots
    for g in data.prob.placement_goals:
        tg = data.prob.duration if g.time is None else g.time
        k = int(np.argmin(np.abs(t - tg)))
        if g.object_id in res.object_pose_knots:
            pose = np.asarray(res.object_pose_knots[g.object_id][k], float)
        else:
            o = data.prob.object(g.object_id)
            pose = np.concatenate([np.asarray(o.position, float), o.rpy()])
        dp = float(np.linalg.norm(pose[:3] - np.asarray(g.position, float)))
        dyaw = abs(float(np.remainder(pose[5] - g.yaw + np.pi, 2 * np.pi) - np.pi))
        if not worst[2] or (dp / TOL["placement"] + dyaw / TOL["placement_yaw"]
                            > worst[0] / TOL["placement"] + worst[1] / TOL["placement_yaw"]):
            worst = (dp, dyaw, g.object_id, float(t[k]))
    return worst


def off_support(data, res) -> tuple:
    """Worst (m, object id, t) distance by which a resting object's centre lies outside the top it
    rests on (<= 0: over it), at the knots where the TO has it set down on another object.

    Why: a box set down with its centre past the top's edge falls off; S2's plans once set the box
    down at deck height with its footprint 1 cm over the trolley's edge (docs/to.md, session 28)."""
    from .discretize import obj_prims_world, outside_top

    worst = (-np.inf, "", 0.0)
    for oid, poses in res.object_pose_knots.items():
        if oid not in data.midx:
            continue
        for k in range(min(len(poses), data.grid.K)):
            sup = data.support_under(k, oid)
            if sup is None:
                continue
            s = data.prob.object(sup[0])
            sp = res.object_pose_knots.get(sup[0])
            out = outside_top(poses[k], *obj_prims_world(s, *((sp[k][:3], sp[k][3:]) if sp is not None else ()))[sup[1]])
            if out > worst[0]:
                worst = (out, oid, float(res.t_knots[k]))
    return worst


def run_checks(model: G1Model, data, res) -> dict:
    """All checks as {name: {"value", "where", "ok"}}."""
    out = {}
    v, w = friction_cone_violation(res, data.w["mu_foot"], data.w["mu_hand"])
    out["friction_cone"] = {"value": v, "where": f"{w[0]} t={w[1]:.2f}", "ok": v <= TOL["friction_cone"] * model.mass * 9.81}
    v, tt = momentum_rate_residual(model, res)
    out["momentum_rate"] = {"value": v, "where": f"t={tt:.2f}", "ok": v <= TOL["momentum_rate"] * model.mass * 9.81}
    v, w = foot_slip(res)
    out["foot_slip"] = {"value": v, "where": f"{w[0]} t={w[1]:.2f}", "ok": v <= TOL["foot_slip"]}
    pen = res.stats.max_penetration
    # reported, not gated: the rows hold at knots only (the demo's pushes that execute pass 1-5 cm
    # between knots; S1's plans up to 15 cm)
    between, tb = penetration_between_knots(model, data, res)
    held, held_where = held_object_forearm_depth(model, data, res)
    out["penetration"] = {"value": pen, "where": f"t={res.stats.max_penetration_time:.2f}", "ok": pen <= TOL["penetration"],
                          "between_knots": between, "between_knots_where": f"t={tb:.2f}",
                          "held_object_forearm": held, "held_object_forearm_where": held_where}
    v, w = hand_grip_rotation(model, res)
    out["hand_grip_rotation"] = {"value": v, "where": f"{w[0]} t={w[1]:.2f}", "ok": v <= TOL["hand_grip_rotation"]}
    v, w = joint_limit_violation(model, res)
    out["joint_limits"] = {"value": v, "where": f"{w[0]} t={w[1]:.2f}", "ok": v <= TOL["joint_limits"]}
    v, w, base, rnea = torque_ratio(model, res)
    # between knots: reported, not gated (see torque_ratio_between_knots)
    vb, wb = torque_ratio_between_knots(model, res)
    out["torque_limits"] = {"value": v, "where": f"{w[0]} t={w[1]:.2f}", "ok": v <= TOL["torque_ratio"],
                            "rnea_ratio": rnea, "base_wrench_residual": base,
                            "between_knots": vb, "between_knots_where": f"{wb[0]} t={wb[1]:.2f}"}
    v, tt = momentum_between_knots(model, res)
    out["momentum_between_knots"] = {"value": v, "where": f"t={tt:.2f}", "ok": v <= TOL["momentum_between_knots"]}
    dp, dyaw, oid, tg = placement_error(data, res)
    out["placement_goals"] = {"value": dp, "yaw_error": dyaw, "where": f"{oid} t={tg:.2f}" if oid else "",
                              "ok": dp <= TOL["placement"] and dyaw <= TOL["placement_yaw"]}
    v, oid, tk = off_support(data, res)
    if oid:
        out["set_down_over_support"] = {"value": v, "where": f"{oid} t={tk:.2f}", "ok": v <= 0.0}
    for c in out.values():  # plain Python numbers (the checks go into JSON and messages)
        c["ok"] = bool(c["ok"])
        for key, val in c.items():
            if isinstance(val, np.floating):
                c[key] = float(val)
    return out
