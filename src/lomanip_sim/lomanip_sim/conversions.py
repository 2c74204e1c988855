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
