"""Perception core types <-> ROS messages. The only module of this package besides the node that
touches message classes. Quaternions convert through lomanip_sim.frames."""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from lomanip_sim import frames
from sensor_msgs.msg import CameraInfo, Image
from shape_msgs.msg import SolidPrimitive
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from lomanip_msgs.msg import Contact, ContactSet, ErrorCode, HumanPose, SceneObjects, StageTiming, SubtaskContacts

from .datatypes import PerceptionImage, PinholeCamera, RigidPose
from .errors import INVALID_REQUEST, PerceptionError
from .scene import ObjectGeometry, Primitive

LIMB_COLOURS = {"left_hand": (0.1, 0.8, 0.1), "right_hand": (0.9, 0.1, 0.1), "left_foot": (0.1, 0.4, 1.0),
                "right_foot": (1.0, 0.6, 0.0)}


def pose_to_rigid(pose: Pose) -> RigidPose:
    q = pose.orientation
    quat = np.array([q.w, q.x, q.y, q.z])
    if not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-9:
        raise PerceptionError(INVALID_REQUEST, "camera_pose has a zero or non-finite orientation quaternion")
    R = frames.quat_to_matrix(frames.xyzw_to_wxyz([q.x, q.y, q.z, q.w]))
    return RigidPose(R, np.array([pose.position.x, pose.position.y, pose.position.z]))


def _primitive(p: SolidPrimitive, pose: Pose) -> Primitive | None:
    d = list(p.dimensions)
    pos = np.array([pose.position.x, pose.position.y, pose.position.z])
    o = pose.orientation
    quat = frames.xyzw_to_wxyz([o.x, o.y, o.z, o.w]) if (o.x or o.y or o.z or o.w) else np.array([1.0, 0, 0, 0])
    if p.type == SolidPrimitive.BOX and len(d) >= 3:
        return Primitive("box", (d[0] / 2, d[1] / 2, d[2] / 2), pos, quat)
    if p.type == SolidPrimitive.SPHERE and len(d) >= 1:
        return Primitive("sphere", (d[0],), pos, quat)
    if p.type == SolidPrimitive.CYLINDER and len(d) >= 2:
        return Primitive("cylinder", (d[1], d[0] / 2), pos, quat)
    return None  # cones/prisms: not used by lomanip scenes


def scene_objects_from_msg(msg: SceneObjects) -> list[ObjectGeometry]:
    out = []
    for o in msg.objects:
        prims = tuple(p for p in (_primitive(s, ps) for s, ps in zip(o.primitives, o.primitive_poses)) if p)
        if not prims:
            continue
        pose = pose_to_rigid(o.pose)
        out.append(ObjectGeometry(o.id, o.object_class, pose.t, frames.matrix_to_quat(pose.R), prims, o.movable))
    return out


def rgb_from_msg(msg: Image) -> np.ndarray:
    if msg.height == 0 or msg.width == 0 or not len(msg.data):
        raise PerceptionError(INVALID_REQUEST, "RGB image is empty")
    ch = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4}.get(msg.encoding)
    if ch is None:
        raise PerceptionError(INVALID_REQUEST, f"RGB encoding {msg.encoding!r} not supported (rgb8, bgr8, rgba8, bgra8)")
    buf = np.frombuffer(bytes(msg.data), np.uint8)
    if buf.size != msg.height * msg.step:
        raise PerceptionError(INVALID_REQUEST, "RGB image data size does not match height x step")
    img = buf.reshape(msg.height, msg.step)[:, : msg.width * ch].reshape(msg.height, msg.width, ch)[..., :3]
    return np.ascontiguousarray(img[..., ::-1] if msg.encoding.startswith("bgr") else img)


def depth_from_msg(msg: Image) -> np.ndarray:
    if msg.height == 0 or msg.width == 0 or not len(msg.data):
        raise PerceptionError(INVALID_REQUEST, "depth image is empty")
    if msg.encoding == "32FC1":
        dt, scale = np.dtype(np.float32), 1.0
    elif msg.encoding == "16UC1":
        dt, scale = np.dtype(np.uint16), 0.001
    else:
        raise PerceptionError(INVALID_REQUEST, f"depth encoding {msg.encoding!r} not supported (32FC1 metres, 16UC1 mm)")
    dt = dt.newbyteorder(">" if msg.is_bigendian else "<")
    buf = np.frombuffer(bytes(msg.data), np.uint8)
    if buf.size != msg.height * msg.step:
        raise PerceptionError(INVALID_REQUEST, "depth image data size does not match height x step")
    rows = buf.reshape(msg.height, msg.step)[:, : msg.width * dt.itemsize]
    d = np.ascontiguousarray(rows).view(dt).reshape(msg.height, msg.width).astype(np.float32) * scale
    if msg.encoding == "16UC1":
        d[d == 0] = np.nan
    return d


def camera_from_msg(info: CameraInfo) -> PinholeCamera:
    k = list(info.k)
    if len(k) != 9 or not (k[0] > 0 and k[4] > 0):
        raise PerceptionError(INVALID_REQUEST, "camera_info has no valid intrinsics (K[0], K[4] must be > 0)")
    return PinholeCamera(int(info.width), int(info.height), k[0], k[4], k[2], k[5])


def scene_image_from_msgs(rgb: Image, depth: Image, info: CameraInfo, camera_pose: Pose) -> PerceptionImage:
    image = PerceptionImage(rgb_from_msg(rgb), depth_from_msg(depth), camera_from_msg(info), pose_to_rigid(camera_pose),
                            source="request")  # fmt: skip
    if image.depth.shape != image.rgb.shape[:2]:
        raise PerceptionError(INVALID_REQUEST, f"depth {image.depth.shape} and RGB {image.rgb.shape[:2]} sizes differ")
    return image


def _pt(p) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def contact_set_msg(results, stamp, frame_id: str = "world") -> ContactSet:
    msg = ContactSet(header=Header(stamp=stamp, frame_id=frame_id))
    for r in results:
        sub = SubtaskContacts(subtask_index=r.index, prompt=r.prompt)
        for c in r.contacts:
            sub.contacts.append(Contact(limb=c.limb, object_id=c.object_id, position=_pt(c.position),
                                        normal=Vector3(x=float(c.normal[0]), y=float(c.normal[1]), z=float(c.normal[2])),
                                        confidence=float(c.confidence)))  # fmt: skip
        msg.subtasks.append(sub)
    return msg


def human_pose_msgs(results, stamp, frame_id: str = "world") -> list[HumanPose]:
    out = []
    for r in results:
        names = list(r.keypoints_world)
        m = HumanPose(header=Header(stamp=stamp, frame_id=frame_id), subtask_index=r.index, keypoint_names=names,
                      keypoints=[_pt(r.keypoints_world[n]) for n in names], joint_names=list(r.joint_names),
                      joint_angles=[float(a) for a in r.joint_angles], confidence=float(r.pose_confidence))  # fmt: skip
        if "pelvis" in r.keypoints_world:
            w, x, y, z = (float(v) for v in r.root_quat)
            m.root_pose = Pose(position=_pt(r.keypoints_world["pelvis"]), orientation=Quaternion(x=x, y=y, z=z, w=w))
        out.append(m)
    return out


def timing_msgs(results, extra: dict[str, float] | None = None) -> list[StageTiming]:
    out = [StageTiming(stage=k, seconds=float(v)) for k, v in (extra or {}).items()]
    for r in results:
        out += [StageTiming(stage=f"subtask{r.index}/{k}", seconds=float(v)) for k, v in r.timings.items()]
    return out


def error_msg(code: str, message: str = "") -> ErrorCode:
    return ErrorCode(val=int(getattr(ErrorCode, code, ErrorCode.FAILURE)), message=message)


def markers_msg(results, stamp, frame_id: str = "world") -> MarkerArray:
    arr = MarkerArray(markers=[Marker(action=Marker.DELETEALL, ns="lomanip_contacts")])
    mid = 0
    for r in results:
        for c in r.contacts:
            rgb = LIMB_COLOURS.get(c.limb, (0.8, 0.8, 0.8))
            colour = ColorRGBA(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0)
            hdr = Header(stamp=stamp, frame_id=frame_id)
            s = Marker(header=hdr, ns="lomanip_contacts", id=mid, type=Marker.SPHERE, action=Marker.ADD, color=colour)
            s.pose.position = _pt(c.position)
            s.pose.orientation.w = 1.0
            s.scale = Vector3(x=0.05, y=0.05, z=0.05)
            a = Marker(header=hdr, ns="lomanip_contact_normals", id=mid, type=Marker.ARROW, action=Marker.ADD, color=colour)
            a.points = [_pt(c.position), _pt(np.asarray(c.position) + 0.12 * np.asarray(c.normal))]
            a.scale = Vector3(x=0.01, y=0.02, z=0.03)
            t = Marker(header=hdr, ns="lomanip_contact_labels", id=mid, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD,
                       color=ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0), text=f"{r.index}:{c.limb}")  # fmt: skip
            t.pose.position = _pt(np.asarray(c.position) + np.array([0, 0, 0.08]))
            t.pose.orientation.w = 1.0
            t.scale.z = 0.05
            arr.markers += [s, a, t]
            mid += 1
    return arr
