"""ROS messages <-> TO core types (lomanip_to.problem / lomanip_to.result).

The only module of lomanip_to that touches message classes. Conventions on the message side:
* SceneObject frames may sit anywhere; the TO wants them at the centre of mass, so the frame is
  shifted by inertia.com here (primitives move the opposite way).
* ContactPhase.contact_poses: the contact frame's z axis is the outward surface normal. A pose
  whose quaternion is all zeros means "position free": the TO chooses the foothold (feet only).
  contact_headings (empty, or one per limb): a foot's heading at its foothold, NaN = none.
* SolidPrimitive SPHERE and CONE are passed as their bounding box (the TO handles boxes and
  cylinders); named simplification.
* A ROLLING object's rear axle is taken from its wheels: the mean position of the two cylinder
  primitives furthest back (most negative x in the object frame).
"""
from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Pose, Quaternion, Transform, Twist, Vector3, Wrench
from shape_msgs.msg import SolidPrimitive
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint, MultiDOFJointTrajectory, \
    MultiDOFJointTrajectoryPoint

from lomanip_msgs.msg import (ContactPhase as ContactPhaseMsg, ContactWrench, CostWeight, KnotWrenches, ObjectMotion as
                              ObjectMotionMsg, ObjectTrajectory, SolverOption, SolverStatistics, SubtaskOptions,
                              TrajectoryOptions, WholeBodyTrajectory)

from . import problem as P

ROBOT_NAME = "unitree_g1_29dof_rev_1_0"
BASE_JOINT = "floating_base"


def duration_to_s(d: Duration) -> float:
    return d.sec + d.nanosec * 1e-9


def s_to_duration(t: float) -> Duration:
    # round once, then split: 7.9999999999 s must become 8 s, not 7 s + 0 ns
    sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return Duration(sec=int(sec), nanosec=int(nanosec))


def _quat_xyzw(q: Quaternion) -> np.ndarray:
    return np.array([q.x, q.y, q.z, q.w], float)


def _rot(q_xyzw) -> np.ndarray:
    x, y, z, w = q_xyzw
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _yaw(q_xyzw) -> float:
    x, y, z, w = q_xyzw
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


# --- requests -> problem -----------------------------------------------------------------------
def primitive_from_msg(prim: SolidPrimitive, pose: Pose, com: np.ndarray) -> P.Primitive:
    d = list(prim.dimensions)
    pos = (pose.position.x - com[0], pose.position.y - com[1], pose.position.z - com[2])
    yaw = _yaw(_quat_xyzw(pose.orientation)) if any(_quat_xyzw(pose.orientation)) else 0.0
    if prim.type == SolidPrimitive.BOX and len(d) == 3:
        return P.Primitive("box", tuple(d), pos, yaw)
    if prim.type == SolidPrimitive.CYLINDER and len(d) == 2:
        # A cylinder lying on its side (wheel) is passed as its bounding box, upright as a cylinder.
        R = _rot(_quat_xyzw(pose.orientation)) if any(_quat_xyzw(pose.orientation)) else np.eye(3)
        if abs(R[2, 2]) > 0.99:
            return P.Primitive("cylinder", (d[0], d[1]), pos, yaw)
        half = np.abs(R) @ np.array([d[1], d[1], 0.5 * d[0]])
        return P.Primitive("box", tuple(2 * half), pos, 0.0)
    if prim.type == SolidPrimitive.SPHERE and len(d) == 1:
        return P.Primitive("box", (2 * d[0],) * 3, pos, 0.0)
    if prim.type == SolidPrimitive.CONE and len(d) == 2:
        return P.Primitive("box", (2 * d[1], 2 * d[1], d[0]), pos, yaw)
    raise P.ProblemError(P.INVALID_REQUEST, f"unsupported primitive type {prim.type} with dimensions {d}",
                         "scene.primitives")


def scene_from_msg(scene) -> list[P.SceneObject]:
    objects = []
    for o in scene.objects:
        com = np.array([o.inertia.com.x, o.inertia.com.y, o.inertia.com.z])
        q = _quat_xyzw(o.pose.orientation)
        R = _rot(q / (np.linalg.norm(q) or 1.0))
        pos = np.array([o.pose.position.x, o.pose.position.y, o.pose.position.z]) + R @ com
        inertia = ((o.inertia.ixx, o.inertia.ixy, o.inertia.ixz), (o.inertia.ixy, o.inertia.iyy, o.inertia.iyz),
                   (o.inertia.ixz, o.inertia.iyz, o.inertia.izz))
        prims = [primitive_from_msg(p, pose, com) for p, pose in zip(o.primitives, o.primitive_poses)]
        wheels = sorted((p for p, m in zip(prims, o.primitives) if m.type == SolidPrimitive.CYLINDER),
                        key=lambda p: p.position[0])
        rear_axle = tuple(np.mean([w.position for w in wheels[:2]], axis=0)) if len(wheels) >= 2 else (0.0, 0.0, 0.0)
        objects.append(P.SceneObject(id=o.id, object_class=o.object_class, movable=o.movable,
                                     position=tuple(pos), quat_xyzw=tuple(q), mass=float(o.inertia.m),
                                     com=(0.0, 0.0, 0.0), inertia=inertia, primitives=prims,
                                     rear_axle=rear_axle))
    return objects


def _joint_vector(names, positions, joint_names, where: str) -> tuple:
    if len(names) != len(positions):
        raise P.ProblemError(P.INVALID_REQUEST, f"{len(names)} joint names but {len(positions)} positions", where)
    by_name = dict(zip(names, positions))
    missing = [j for j in joint_names if j not in by_name]
    unknown = [n for n in names if n not in joint_names]
    if missing or unknown:
        raise P.ProblemError(P.INVALID_REQUEST, f"joint names do not match the G1: missing {missing[:3]}"
                             f"{'...' if len(missing) > 3 else ''}, unknown {unknown[:3]}", where)
    return tuple(float(by_name[j]) for j in joint_names)


def keyframes_from_msg(kf_array, joint_names) -> list[P.Keyframe]:
    keyframes = []
    for i, kf in enumerate(kf_array.keyframes):
        where = f"keyframes[{i}]"
        b = kf.base_pose
        keyframes.append(P.Keyframe(
            subtask_index=int(kf.subtask_index),
            base_position=(b.position.x, b.position.y, b.position.z),
            base_quat_xyzw=tuple(_quat_xyzw(b.orientation)),
            joints=_joint_vector(kf.joints.name, kf.joints.position, joint_names, where + ".joints"),
            contacts=[P.ContactSpec(c.limb, c.object_id, (c.position.x, c.position.y, c.position.z),
                                    (c.normal.x, c.normal.y, c.normal.z)) for c in kf.contacts],
            desired_foot_xy=(kf.desired_foot_position.x, kf.desired_foot_position.y)
            if kf.reference_object_id or any((kf.desired_foot_position.x, kf.desired_foot_position.y)) else None,
            reference_object_id=kf.reference_object_id, prompt=kf.prompt))
    return keyframes


def schedule_from_msg(schedule) -> list[P.ContactPhase]:
    phases = []
    for i, ph in enumerate(schedule.phases):
        where = f"contact_schedule.phases[{i}]"
        n = len(ph.limbs_in_contact)
        if (len(ph.contact_object_ids) != n or (ph.contact_poses and len(ph.contact_poses) != n)
                or (len(ph.contact_headings) and len(ph.contact_headings) != n)):
            raise P.ProblemError(P.INVALID_REQUEST, "limbs_in_contact, contact_object_ids, contact_poses and "
                                 "contact_headings must have the same length", where)
        contacts = {}
        for j, (limb, oid) in enumerate(zip(ph.limbs_in_contact, ph.contact_object_ids)):
            if limb in contacts:
                raise P.ProblemError(P.INVALID_REQUEST, f"limb {limb!r} listed twice", where)
            position, normal = None, (0.0, 0.0, 1.0)
            if ph.contact_poses:
                pose = ph.contact_poses[j]
                q = _quat_xyzw(pose.orientation)
                if np.linalg.norm(q) > 1e-9:
                    position = (pose.position.x, pose.position.y, pose.position.z)
                    normal = tuple(_rot(q / np.linalg.norm(q))[:, 2])
            heading = float(ph.contact_headings[j]) if len(ph.contact_headings) else math.nan
            contacts[limb] = P.ContactSpec(limb, oid, position, normal, None if math.isnan(heading) else heading)
        objects = {}
        for m in ph.object_motions:
            if m.mode not in P.OBJECT_MODES:
                raise P.ProblemError(P.INVALID_REQUEST, f"object motion mode {m.mode!r} (valid: "
                                     f"{', '.join(P.OBJECT_MODES)})", where)
            objects[m.object_id] = P.ObjectMotion(m.mode, m.support or P.FLOOR, m.attached_to)
        phases.append(P.ContactPhase(start=duration_to_s(ph.start), end=duration_to_s(ph.end),
                                     phase_type=P.WALKING if ph.phase_type == ContactPhaseMsg.WALKING else P.STANCE,
                                     subtask_index=int(ph.subtask_index), contacts=contacts, objects=objects))
    return phases


def options_from_msg(o: TrajectoryOptions, base: P.Options | None = None) -> P.Options:
    return (base or P.Options()).replaced(
        use_keyframe_base_cost=o.use_keyframe_base_cost, use_keyframe_foot_cost=o.use_keyframe_foot_cost,
        use_keyframe_warm_start=o.use_keyframe_warm_start, collision_hard_constraint=o.collision_hard_constraint,
        collision_penalty=o.collision_penalty, collision_homotopy=o.collision_homotopy,
        max_iterations=int(o.max_iterations), output_rate=float(o.output_rate), time_limit=float(o.time_limit),
        inertial_torque_groups=tuple(str(g) for g in o.inertial_torque_groups),
        single_support_com_lateral=float(o.single_support_com_lateral) if o.single_support_com_lateral > 0 else None,
        waist_yaw_range=max(float(o.waist_yaw_range), 0.0),
        interval_momentum_tolerance=max(float(o.interval_momentum_tolerance), 0.0),
        upper_body_acceleration_limit=max(float(o.upper_body_acceleration_limit), 0.0),
        upper_body_speed_limit=max(float(o.upper_body_speed_limit), 0.0),
        carried_object_clearance=max(float(o.carried_object_clearance), 0.0),
        body_object_clearance=max(float(o.body_object_clearance), 0.0),
        hand_object_clearance=max(float(o.hand_object_clearance), 0.0),
        carry_reach=max(float(o.carry_reach), 0.0),
        placement_tolerance=max(float(o.placement_tolerance), 0.0),
        dt_lift=max(float(o.dt_lift), 0.0),
        dt_reach=max(float(o.dt_reach), 0.0),
        lift_with_previous_segment=bool(o.lift_with_previous_segment),
        segment_moving_objects=bool(o.segment_moving_objects),
        load_in_double_support_margin=bool(o.load_in_double_support_margin),
        resting_object_dynamics=bool(o.resting_object_dynamics),
        cop_margin_front=float(o.cop_margin_front),
        cop_margin_side=float(o.cop_margin_side),
        hand_standoff=float(o.hand_standoff),
        forearm_clear_of_held_object=bool(o.forearm_clear_of_held_object),
        final_warm_start_max_violation=float(o.final_warm_start_max_violation),
        final_cold_retry=bool(o.final_cold_retry),
        hold_placement_goals=bool(o.hold_placement_goals),
        collision_screen_distance=float(o.collision_screen_distance),
        ipopt={**(base.ipopt if base is not None else {}),
               **{str(kv.name): P.parse_option_value(str(kv.value)) for kv in o.solver_options}},
        weights={**(base.weights if base is not None else {}), **{str(w.name): float(w.value) for w in o.weights}},
        subtask_options=subtask_options_from_msg(o.subtask_options) if o.subtask_options else
        dict(base.subtask_options if base is not None else {}))


def subtask_options_from_msg(entries) -> dict:
    """{subtask index: {Options name: value}} from SubtaskOptions entries; text that is not a YAML
    mapping, or a subtask given twice, is INVALID_REQUEST (names and values are checked with the
    schedule, ``problem.validate_problem``)."""
    import yaml

    out: dict = {}
    for e in entries:
        sub = int(e.subtask_index)
        if sub in out:
            raise P.ProblemError(P.INVALID_REQUEST, f"options.subtask_options: subtask {sub} given twice", "options")
        try:
            over = yaml.safe_load(e.options_yaml) if e.options_yaml.strip() else {}
        except yaml.YAMLError as err:
            raise P.ProblemError(P.INVALID_REQUEST, f"options.subtask_options[{sub}]: options_yaml is not YAML "
                                                    f"({str(err).splitlines()[0]})", "options") from None
        if not isinstance(over, dict) or not all(isinstance(k, str) for k in over):
            raise P.ProblemError(P.INVALID_REQUEST, f"options.subtask_options[{sub}]: options_yaml must be a mapping "
                                                    f"of option names to values, got {e.options_yaml!r}", "options")
        out[sub] = dict(P.option_item(k, v) for k, v in over.items())
    return out


def subtask_options_msg(subtask_options: dict) -> list:
    """SubtaskOptions entries of ``Options.subtask_options`` (tuples written as YAML lists)."""
    import yaml

    def plain(v):
        if isinstance(v, (tuple, list)):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in v.items()}
        if isinstance(v, (np.floating, np.integer, np.bool_)):
            return v.item()
        return v

    return [SubtaskOptions(subtask_index=int(sub),
                           options_yaml=yaml.safe_dump(plain(over or {}), default_flow_style=True, width=10**6).strip())
            for sub, over in sorted((subtask_options or {}).items())]


def initial_configuration(joints, base_pose: Pose, keyframes: list[P.Keyframe], joint_names) -> tuple:
    """35-D x = (base position, rpy, 29 joints) from the request, or from the first keyframe."""
    from .model import quat_xyzw_to_rot, rot_to_rpy

    if joints.name:
        q = _quat_xyzw(base_pose.orientation)
        if np.linalg.norm(q) < 1e-9:
            raise P.ProblemError(P.INVALID_REQUEST, "initial_base_pose has a zero quaternion", "initial_base_pose")
        rpy = rot_to_rpy(quat_xyzw_to_rot(tuple(q / np.linalg.norm(q))))
        return (base_pose.position.x, base_pose.position.y, base_pose.position.z, *rpy,
                *_joint_vector(joints.name, joints.position, joint_names, "initial_joints"))
    if not keyframes:
        raise P.ProblemError(P.INVALID_REQUEST, "no initial state and no keyframes", "initial_joints")
    return tuple(keyframes[0].x())


def goal_time_from_msg(t: float) -> float | None:
    """The message's ``time`` (0, negative or NaN: at the end of the trajectory) as the TO's optional time."""
    t = float(t)
    return t if math.isfinite(t) and t > 0.0 else None


def placement_goal_from_msg(g) -> P.PlacementGoal:
    return P.PlacementGoal(g.object_id, (g.position.x, g.position.y, g.position.z), float(g.yaw),
                           time=goal_time_from_msg(g.time))


def problem_from_request(req, joint_names, base_options: P.Options | None = None) -> P.Problem:
    keyframes = keyframes_from_msg(req.keyframes, joint_names)
    return P.Problem(objects=scene_from_msg(req.scene), keyframes=keyframes,
                     phases=schedule_from_msg(req.contact_schedule),
                     initial_configuration=initial_configuration(req.initial_joints, req.initial_base_pose,
                                                                 keyframes, joint_names),
                     placement_goals=[placement_goal_from_msg(g) for g in req.placement_goals],
                     options=options_from_msg(req.options, base_options), name=req.scene.scenario)


# --- result -> messages ------------------------------------------------------------------------
def _v3(a) -> Vector3:
    return Vector3(x=float(a[0]), y=float(a[1]), z=float(a[2]))


def _pt(a) -> Point:
    return Point(x=float(a[0]), y=float(a[1]), z=float(a[2]))


def _q(a) -> Quaternion:
    return Quaternion(x=float(a[0]), y=float(a[1]), z=float(a[2]), w=float(a[3]))


def joint_trajectory_msg(res, stamp, frame_id: str = "world") -> JointTrajectory:
    msg = JointTrajectory(joint_names=list(res.joint_names))
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    for i, t in enumerate(res.t):
        msg.points.append(JointTrajectoryPoint(positions=res.joint_positions[i].tolist(),
                                               velocities=res.joint_velocities[i].tolist(),
                                               time_from_start=s_to_duration(float(t))))
    return msg


def base_trajectory_msg(res, stamp, frame_id: str = "world") -> MultiDOFJointTrajectory:
    msg = MultiDOFJointTrajectory(joint_names=[BASE_JOINT])
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    for i, t in enumerate(res.t):
        msg.points.append(MultiDOFJointTrajectoryPoint(
            transforms=[Transform(translation=_v3(res.base_position[i]), rotation=_q(res.base_quat_xyzw[i]))],
            velocities=[Twist(linear=_v3(res.base_linear_velocity[i]), angular=_v3(res.base_angular_velocity[i]))],
            time_from_start=s_to_duration(float(t))))
    return msg


def schedule_msg(phases: list[P.ContactPhase]):
    from lomanip_msgs.msg import ContactSchedule

    out = ContactSchedule()
    for ph in phases:
        m = ContactPhaseMsg(phase_type=ContactPhaseMsg.WALKING if ph.phase_type == P.WALKING else ContactPhaseMsg.STANCE,
                            subtask_index=int(ph.subtask_index), start=s_to_duration(ph.start), end=s_to_duration(ph.end))
        headed = any(c.heading is not None for c in ph.contacts.values())
        for limb, c in ph.contacts.items():
            m.limbs_in_contact.append(limb)
            m.contact_object_ids.append(c.object_id)
            if headed:
                m.contact_headings.append(float("nan") if c.heading is None else float(c.heading))
            if c.position is None:
                m.contact_poses.append(Pose(orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)))
            else:
                m.contact_poses.append(Pose(position=_pt(c.position), orientation=_normal_quat(c.normal)))
        for oid, mo in ph.objects.items():
            m.object_motions.append(ObjectMotionMsg(object_id=oid, mode=mo.mode, support=mo.support,
                                                    attached_to=mo.attached_to))
        out.phases.append(m)
    return out


def _normal_quat(n) -> Quaternion:
    """A quaternion whose z axis is the normal n (shortest rotation from +z)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    axis = np.cross([0.0, 0.0, 1.0], n)
    s, c = np.linalg.norm(axis), float(n[2])
    if s < 1e-9:
        return Quaternion(x=0.0, y=0.0, z=0.0, w=1.0) if c > 0 else Quaternion(x=1.0, y=0.0, z=0.0, w=0.0)
    half = math.atan2(s, c) / 2
    a = axis / s * math.sin(half)
    return Quaternion(x=float(a[0]), y=float(a[1]), z=float(a[2]), w=math.cos(half))


def statistics_msg(stats) -> SolverStatistics:
    return SolverStatistics(
        solver=stats.solver, converged=bool(stats.converged), iterations=int(stats.iterations),
        build_time=float(stats.build_time), solve_time=float(stats.solve_time), cost=float(stats.cost),
        max_dynamics_violation=float(stats.max_dynamics_violation.value),
        max_contact_violation=float(stats.max_contact_violation.value),
        max_penetration=float(stats.max_penetration), peak_memory_mb=float(stats.peak_memory_mb),
        status_message=stats.status_message())


def trajectory_msg(res, phases: list[P.ContactPhase], scenario: str, stamp) -> WholeBodyTrajectory:
    """A densified TOResult -> WholeBodyTrajectory (all arrays on the dense time grid)."""
    if res.t is None:
        raise ValueError("TOResult must be densified before conversion")
    msg = WholeBodyTrajectory(robot_name=ROBOT_NAME, scenario=scenario,
                              joint_trajectory=joint_trajectory_msg(res, stamp),
                              base_trajectory=base_trajectory_msg(res, stamp),
                              contact_schedule=schedule_msg(phases), solver_statistics=statistics_msg(res.stats))
    msg.header.stamp, msg.header.frame_id = stamp, "world"
    for oid in res.object_positions:
        msg.object_trajectories.append(ObjectTrajectory(
            object_id=oid,
            poses=[Pose(position=_pt(p), orientation=_q(q)) for p, q in
                   zip(res.object_positions[oid], res.object_quat_xyzw[oid])],
            twists=[Twist(linear=_v3(v), angular=_v3(w)) for v, w in
                    zip(res.object_linear_velocity[oid], res.object_angular_velocity[oid])]))
    for i in range(len(res.t)):
        knot = KnotWrenches()
        for limb, forces in res.forces.items():
            obj = res.contact_objects[limb][i]
            if not obj:
                continue
            knot.wrenches.append(ContactWrench(limb=limb, object_id=obj, point=_pt(res.points[limb][i]),
                                               wrench=Wrench(force=_v3(forces[i]), torque=_v3(res.torques[limb][i]))))
        msg.contact_wrenches.append(knot)
    msg.com_position = [_pt(c) for c in res.com]
    msg.linear_momentum = [_v3(h) for h in res.linear_momentum]
    msg.angular_momentum = [_v3(h) for h in res.angular_momentum]
    return msg


# --- problem -> request (fixtures, planner) ----------------------------------------------------
def request_from_problem(prob: P.Problem, joint_names):
    """An OptimizeTrajectory request that describes ``prob`` (used to send fixtures to the node)."""
    from geometry_msgs.msg import Inertia
    from lomanip_msgs.msg import Contact, Keyframe, KeyframeArray, PlacementGoal, SceneObject, SceneObjects
    from lomanip_msgs.srv import OptimizeTrajectory
    from sensor_msgs.msg import JointState

    from .model import rpy_to_rot, rot_to_quat_xyzw

    req = OptimizeTrajectory.Request()
    req.scene = SceneObjects(scenario=prob.name)
    req.scene.header.frame_id = "world"
    for o in prob.objects:
        I = o.inertia_matrix()
        so = SceneObject(id=o.id, object_class=o.object_class, movable=o.movable,
                         pose=Pose(position=_pt(o.position), orientation=_q(o.quat_xyzw)),
                         inertia=Inertia(m=float(o.mass), ixx=I[0, 0], ixy=I[0, 1], ixz=I[0, 2], iyy=I[1, 1],
                                         iyz=I[1, 2], izz=I[2, 2]))
        for p in o.primitives:
            kind = SolidPrimitive.BOX if p.kind == "box" else SolidPrimitive.CYLINDER
            so.primitives.append(SolidPrimitive(type=kind, dimensions=[float(d) for d in p.size]))
            half = p.yaw / 2
            so.primitive_poses.append(Pose(position=_pt(p.position),
                                           orientation=Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))))
        req.scene.objects.append(so)
    for kf in prob.keyframes:
        m = Keyframe(subtask_index=kf.subtask_index, prompt=kf.prompt, reference_object_id=kf.reference_object_id,
                     base_pose=Pose(position=_pt(kf.base_position), orientation=_q(kf.base_quat_xyzw)),
                     joints=JointState(name=list(joint_names), position=[float(v) for v in kf.joints]))
        if kf.desired_foot_xy is not None:
            m.desired_foot_position = Point(x=float(kf.desired_foot_xy[0]), y=float(kf.desired_foot_xy[1]), z=0.0)
        m.contacts = [Contact(limb=c.limb, object_id=c.object_id, position=_pt(c.position), normal=_v3(c.normal),
                              confidence=1.0) for c in kf.contacts]
        req.keyframes.keyframes.append(m)
    req.contact_schedule = schedule_msg(prob.phases)
    req.placement_goals = [PlacementGoal(object_id=g.object_id, position=_pt(g.position), yaw=float(g.yaw),
                                         time=float(g.time) if g.time is not None else 0.0)
                           for g in prob.placement_goals]
    o = prob.options
    req.options = TrajectoryOptions(
        use_keyframe_base_cost=o.use_keyframe_base_cost, use_keyframe_foot_cost=o.use_keyframe_foot_cost,
        use_keyframe_warm_start=o.use_keyframe_warm_start, collision_hard_constraint=o.collision_hard_constraint,
        collision_penalty=o.collision_penalty, collision_homotopy=o.collision_homotopy,
        max_iterations=int(o.max_iterations), output_rate=float(o.output_rate), time_limit=float(o.time_limit),
        inertial_torque_groups=list(o.inertial_torque_groups),
        single_support_com_lateral=float(o.single_support_com_lateral or 0.0),
        waist_yaw_range=float(o.waist_yaw_range),
        interval_momentum_tolerance=float(o.interval_momentum_tolerance),
        upper_body_acceleration_limit=float(o.upper_body_acceleration_limit),
        upper_body_speed_limit=float(o.upper_body_speed_limit),
        carried_object_clearance=float(o.carried_object_clearance),
        body_object_clearance=float(o.body_object_clearance),
        hand_object_clearance=float(o.hand_object_clearance),
        carry_reach=float(o.carry_reach),
        placement_tolerance=float(o.placement_tolerance),
        dt_lift=float(o.dt_lift),
        dt_reach=float(o.dt_reach),
        lift_with_previous_segment=bool(o.lift_with_previous_segment),
        segment_moving_objects=bool(o.segment_moving_objects),
        load_in_double_support_margin=bool(o.load_in_double_support_margin),
        resting_object_dynamics=bool(o.resting_object_dynamics),
        cop_margin_front=float(o.cop_margin_front),
        cop_margin_side=float(o.cop_margin_side),
        hand_standoff=float(o.hand_standoff),
        forearm_clear_of_held_object=bool(o.forearm_clear_of_held_object),
        final_warm_start_max_violation=float(o.final_warm_start_max_violation),
        final_cold_retry=bool(o.final_cold_retry),
        hold_placement_goals=bool(o.hold_placement_goals),
        collision_screen_distance=float(o.collision_screen_distance),
        solver_options=[SolverOption(name=str(k), value=str(v)) for k, v in (o.ipopt or {}).items()],
        weights=[CostWeight(name=str(k), value=float(v)) for k, v in (o.weights or {}).items()],
        subtask_options=subtask_options_msg(o.subtask_options))
    if prob.initial_configuration is not None:
        x0 = np.asarray(prob.initial_configuration, float)
        req.initial_base_pose = Pose(position=_pt(x0[:3]), orientation=_q(rot_to_quat_xyzw(rpy_to_rot(x0[3:6]))))
        req.initial_joints = JointState(name=list(joint_names), position=x0[6:].tolist())
    return req
