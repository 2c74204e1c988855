"""Core simulation types <-> ROS messages. The only place lomanip_sim touches message classes.

Quaternions: core types hold MuJoCo order (w, x, y, z); messages hold ROS order (x, y, z, w). The
conversion goes through lomanip_sim.frames so it happens in one place.
"""
from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Inertia, Point, Pose, Quaternion, Transform, TransformStamped, Twist, Vector3
from sensor_msgs.msg import CameraInfo, Image, JointState
from shape_msgs.msg import SolidPrimitive

from lomanip_msgs.msg import SceneObject, SceneObjects

from . import frames

_PRIMITIVE_TYPES = {"box": SolidPrimitive.BOX, "sphere": SolidPrimitive.SPHERE,
                    "cylinder": SolidPrimitive.CYLINDER}


def pose_msg(pos, quat_wxyz) -> Pose:
    x, y, z, w = frames.wxyz_to_xyzw(quat_wxyz)
    return Pose(position=Point(x=float(pos[0]), y=float(pos[1]), z=float(pos[2])),
                orientation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)))


def pose_from_msg(pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    q = pose.orientation
    return (np.array([pose.position.x, pose.position.y, pose.position.z]),
            frames.xyzw_to_wxyz([q.x, q.y, q.z, q.w]))


def transform_msg(stamp: Time, parent: str, child: str, pos, quat_wxyz) -> TransformStamped:
    p = pose_msg(pos, quat_wxyz)
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform = Transform(translation=Vector3(x=p.position.x, y=p.position.y, z=p.position.z),
                            rotation=p.orientation)
    return t


def vec3(v) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def scene_object_msg(obj) -> SceneObject:
    """lomanip_sim.simulator.ObjectState -> SceneObject."""
    inertia = np.asarray(obj.inertia, dtype=float)
    msg = SceneObject(id=obj.id, object_class=obj.object_class, movable=bool(obj.movable),
                      pose=pose_msg(obj.pos, obj.quat),
                      twist=Twist(linear=vec3(obj.linvel), angular=vec3(obj.angvel)),
                      inertia=Inertia(m=float(obj.mass), com=vec3(obj.com),
                                      ixx=inertia[0, 0], ixy=inertia[0, 1], ixz=inertia[0, 2],
                                      iyy=inertia[1, 1], iyz=inertia[1, 2], izz=inertia[2, 2]))
    for prim in obj.primitives:
        if prim.type == "capsule":
            # SolidPrimitive has no capsule: send it exactly as a cylinder plus two end spheres.
            radius, half = prim.size[0], prim.size[1]
            axis = frames.quat_to_matrix(prim.quat)[:, 2]
            msg.primitives.append(SolidPrimitive(type=SolidPrimitive.CYLINDER, dimensions=[2.0 * half, radius]))
            msg.primitive_poses.append(pose_msg(prim.pos, prim.quat))
            for sign in (-1.0, 1.0):
                msg.primitives.append(SolidPrimitive(type=SolidPrimitive.SPHERE, dimensions=[radius]))
                msg.primitive_poses.append(pose_msg(np.asarray(prim.pos) + sign * half * axis, prim.quat))
            continue
        msg.primitives.append(SolidPrimitive(type=_PRIMITIVE_TYPES[prim.type],
                                             dimensions=[float(d) for d in prim.solid_primitive_dimensions()]))
        msg.primitive_poses.append(pose_msg(prim.pos, prim.quat))
    return msg


def scene_objects_msg(stamp: Time, scenario: str, parameters_yaml: str, objects) -> SceneObjects:
    msg = SceneObjects(scenario=scenario, parameters_yaml=parameters_yaml,
                       objects=[scene_object_msg(o) for o in objects])
    msg.header.stamp = stamp
    msg.header.frame_id = "world"
    return msg


def joint_state_msg(stamp: Time, names, q, v, tau) -> JointState:
    msg = JointState(name=list(names), position=[float(x) for x in q], velocity=[float(x) for x in v],
                     effort=[float(x) for x in tau])
    msg.header.stamp = stamp
    return msg


def rgb_msg(stamp: Time, frame_id: str, rgb: np.ndarray) -> Image:
    h, w, _ = rgb.shape
    msg = Image(height=h, width=w, encoding="rgb8", is_bigendian=0, step=w * 3)
    msg.data = np.ascontiguousarray(rgb, dtype=np.uint8).tobytes()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    return msg


def depth_msg(stamp: Time, frame_id: str, depth: np.ndarray) -> Image:
    """32FC1 metres along the optical axis (REP 118): +inf where nothing is in range."""
    h, w = depth.shape
    msg = Image(height=h, width=w, encoding="32FC1", is_bigendian=0, step=w * 4)
    msg.data = np.ascontiguousarray(depth, dtype=np.float32).tobytes()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    return msg


def camera_info_msg(stamp: Time, frame_id: str, width: int, height: int, fx: float, fy: float,
                    cx: float, cy: float) -> CameraInfo:
    """A distortion-free pinhole CameraInfo (MuJoCo renders an ideal pinhole)."""
    msg = CameraInfo(width=width, height=height, distortion_model="plumb_bob", d=[0.0] * 5)
    msg.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    return msg


# --- whole-body trajectories and execution metrics -----------------------------------------------
def _duration_s(d) -> float:
    return float(d.sec) + 1e-9 * float(d.nanosec)


def _normal_from_pose(pose: Pose) -> tuple[np.ndarray | None, np.ndarray]:
    """Contact pose -> (position, outward normal = the pose's z axis); a zero quaternion = free contact."""
    q = pose.orientation
    xyzw = np.array([q.x, q.y, q.z, q.w], dtype=float)
    if np.linalg.norm(xyzw) < 1e-9:
        return None, np.array([0.0, 0.0, 1.0])
    R = frames.quat_to_matrix(frames.xyzw_to_wxyz(xyzw / np.linalg.norm(xyzw)))
    return np.array([pose.position.x, pose.position.y, pose.position.z]), R[:, 2]


def trajectory_from_msg(msg):
    """lomanip_msgs/WholeBodyTrajectory -> lomanip_sim.trajectory.Trajectory (raises TrajectoryError).

    Every array must be on the joint trajectory's time grid: the base trajectory point for point,
    object trajectories and contact wrenches (when given) one entry per point.
    """
    from .trajectory import INVALID_TRAJECTORY, LimbContact, Phase, TrajectoryError, check_time_grid, make_trajectory

    def bad(text: str):
        return TrajectoryError(INVALID_TRAJECTORY, text)

    jt, bt = msg.joint_trajectory, msg.base_trajectory
    n = len(jt.points)
    if n < 2:
        raise bad(f"joint_trajectory needs at least 2 points, got {n}")
    names = list(jt.joint_names)
    for i, p in enumerate(jt.points):
        if len(p.positions) != len(names):
            raise bad(f"joint_trajectory.points[{i}] has {len(p.positions)} positions for {len(names)} joint names")
        if p.velocities and len(p.velocities) != len(names):
            raise bad(f"joint_trajectory.points[{i}] has {len(p.velocities)} velocities for {len(names)} joint names")
    t = check_time_grid([_duration_s(p.time_from_start) for p in jt.points])
    q = np.array([list(p.positions) for p in jt.points], dtype=float)
    qd = np.array([list(p.velocities) for p in jt.points], dtype=float) if all(p.velocities for p in jt.points) else None
    if len(bt.points) != n:
        raise bad(f"base_trajectory has {len(bt.points)} points, joint_trajectory {n}: they must share one time grid")
    tb = np.array([_duration_s(p.time_from_start) for p in bt.points])
    if np.max(np.abs(tb - t)) > 1e-6:
        i = int(np.argmax(np.abs(tb - t)))
        raise bad(f"base_trajectory.points[{i}] is at t={tb[i]:.4f} s, joint point at {t[i]:.4f} s (one time grid)")
    if any(len(p.transforms) != 1 for p in bt.points):
        raise bad("base_trajectory points need exactly one transform (the pelvis pose)")
    base = np.array([[p.transforms[0].translation.x, p.transforms[0].translation.y, p.transforms[0].translation.z]
                     for p in bt.points])
    quat = np.array([frames.xyzw_to_wxyz([r.x, r.y, r.z, r.w]) if (r.x, r.y, r.z, r.w) != (0, 0, 0, 0) else [0, 0, 0, 0]
                     for r in (p.transforms[0].rotation for p in bt.points)], dtype=float)
    lin = ang = None
    if all(p.velocities for p in bt.points):
        lin = np.array([[v.linear.x, v.linear.y, v.linear.z] for v in (p.velocities[0] for p in bt.points)])
        ang = np.array([[v.angular.x, v.angular.y, v.angular.z] for v in (p.velocities[0] for p in bt.points)])
    phases = []
    says_motions = any(ph.object_motions for ph in msg.contact_schedule.phases)  # none at all: not said
    for k, ph in enumerate(msg.contact_schedule.phases):
        if len(ph.contact_object_ids) != len(ph.limbs_in_contact) or (
                ph.contact_poses and len(ph.contact_poses) != len(ph.limbs_in_contact)):
            raise bad(f"contact_schedule.phases[{k}]: limbs_in_contact, contact_object_ids and contact_poses differ in length")
        contacts = {}
        for j, (limb, oid) in enumerate(zip(ph.limbs_in_contact, ph.contact_object_ids)):
            pos, normal = _normal_from_pose(ph.contact_poses[j]) if ph.contact_poses else (None, np.array([0.0, 0.0, 1.0]))
            contacts[limb] = LimbContact(oid, pos, normal)
        free = frozenset(mo.object_id for mo in ph.object_motions if mo.mode == "free") if says_motions else None
        phases.append(Phase(_duration_s(ph.start), _duration_s(ph.end), contacts, walking=ph.phase_type == 1,
                            free_objects=free))
    forces, torques, points = {}, {}, {}
    if msg.contact_wrenches:
        if len(msg.contact_wrenches) != n:
            raise bad(f"contact_wrenches has {len(msg.contact_wrenches)} entries for {n} points")
        for i, knot in enumerate(msg.contact_wrenches):
            for w in knot.wrenches:
                forces.setdefault(w.limb, np.zeros((n, 3)))[i] = [w.wrench.force.x, w.wrench.force.y, w.wrench.force.z]
                torques.setdefault(w.limb, np.zeros((n, 3)))[i] = [w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z]
                points.setdefault(w.limb, np.full((n, 3), np.nan))[i] = [w.point.x, w.point.y, w.point.z]
    objects = {}
    for ot in msg.object_trajectories:
        if len(ot.poses) != n:
            raise bad(f"object_trajectories[{ot.object_id!r}] has {len(ot.poses)} poses for {n} points")
        try:
            poses = [pose_from_msg(p) for p in ot.poses]
        except frames.FrameError as e:
            raise bad(f"object_trajectories[{ot.object_id!r}]: {e}") from None
        objects[ot.object_id] = (np.array([p for p, _ in poses]), np.array([qq for _, qq in poses]))
    angmom = None
    if msg.angular_momentum:  # optional: without it the controller has no momentum task
        if len(msg.angular_momentum) != n:
            raise bad(f"angular_momentum has {len(msg.angular_momentum)} entries for {n} points")
        angmom = np.array([[v.x, v.y, v.z] for v in msg.angular_momentum])
    return make_trajectory(t, names, q, qd, base, quat, lin, ang, phases=phases, forces=forces, torques=torques,
                           points=points, objects=objects, scenario=msg.scenario, robot_name=msg.robot_name,
                           angular_momentum=angmom)  # fmt: skip


def execution_metrics_msg(m):
    """lomanip_sim.execution.ExecutionMetrics -> lomanip_msgs/ExecutionMetrics."""
    from lomanip_msgs.msg import ExecutionMetrics

    return ExecutionMetrics(
        task_success=bool(m.task_success), task_success_detail=str(m.task_success_detail), fell=bool(m.fell),
        duration=float(m.duration), real_time_factor=float(m.real_time_factor),
        max_base_position_error=float(m.max_base_position_error), rms_base_position_error=float(m.rms_base_position_error),
        max_joint_error=float(m.max_joint_error), rms_joint_error=float(m.rms_joint_error),
        final_object_position_error=float(m.final_object_position_error),
        final_object_yaw_error=float(m.final_object_yaw_error))  # fmt: skip
