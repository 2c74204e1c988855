"""Messages <-> planner core types. The only module of lomanip_planner that touches messages
(besides the node)."""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from sensor_msgs.msg import JointState

from lomanip_msgs.msg import Contact, Keyframe, KeyframeArray
from lomanip_sim import frames
from lomanip_sim.robot_model import G1_JOINT_NAMES
from lomanip_to.problem import FLOOR, PlacementGoal

from .keyframes import SubtaskPerception
from .retargeting import LimbTarget, pelvis_height_ratio


def robot_qpos(joints: JointState, pelvis_transform) -> np.ndarray:
    """MuJoCo-order qpos (36) of the G1 from /joint_states and the world->pelvis transform."""
    by_name = dict(zip(joints.name, joints.position))
    missing = [j for j in G1_JOINT_NAMES if j not in by_name]
    if missing:
        raise ValueError(f"/joint_states lacks {missing[:3]}")
    t, r = pelvis_transform.translation, pelvis_transform.rotation
    return np.array([t.x, t.y, t.z, *frames.xyzw_to_wxyz([r.x, r.y, r.z, r.w]),
                     *[by_name[j] for j in G1_JOINT_NAMES]])


def _vec(v) -> np.ndarray:
    return np.array([v.x, v.y, v.z], float)


def subtasks_from_perception(contact_set, human_poses, prompts: list[str]) -> list[SubtaskPerception]:
    """ContactSet + HumanPose[] -> one SubtaskPerception per prompt (joint angles whose names are
    G1 joints become the posture prior; others are ignored)."""
    poses = {p.subtask_index: p for p in human_poses}
    by_index = {s.subtask_index: s for s in contact_set.subtasks}
    out = []
    for i, prompt in enumerate(prompts):
        sub = by_index.get(i)
        contacts = [] if sub is None else [
            LimbTarget(c.limb, _vec(c.position), _vec(c.normal), c.object_id or FLOOR) for c in sub.contacts]
        pose = poses.get(i)
        orientation, prior, ratio = None, {}, None
        if pose is not None:
            ratio = pelvis_height_ratio({n: _vec(p) for n, p in zip(pose.keypoint_names, pose.keypoints)})
            q = pose.root_pose.orientation
            if abs(q.x) + abs(q.y) + abs(q.z) + abs(q.w) > 0:
                # Keep the heading of the human pelvis; roll and pitch come from the IK.
                yaw = frames.quat_to_yaw(frames.xyzw_to_wxyz([q.x, q.y, q.z, q.w]))
                orientation = frames.yaw_to_quat(yaw)
            prior = {n: float(a) for n, a in zip(pose.joint_names, pose.joint_angles) if n in G1_JOINT_NAMES}
        out.append(SubtaskPerception(i, prompt, contacts, orientation, prior, ratio))
    return out


def placement_goal(msg) -> PlacementGoal:
    """lomanip_msgs/PlacementGoal as the TO's type (the same conversion as the TO node's)."""
    from lomanip_to.conversions import placement_goal_from_msg

    return placement_goal_from_msg(msg)


def keyframe_array_msg(keyframes, stamp) -> KeyframeArray:
    """lomanip_to.problem.Keyframe list -> KeyframeArray."""
    out = KeyframeArray()
    out.header.stamp, out.header.frame_id = stamp, "world"
    for kf in keyframes:
        x, y, z, w = kf.base_quat_xyzw
        m = Keyframe(subtask_index=int(kf.subtask_index), prompt=kf.prompt, reference_object_id=kf.reference_object_id,
                     base_pose=Pose(position=Point(x=float(kf.base_position[0]), y=float(kf.base_position[1]),
                                                   z=float(kf.base_position[2])),
                                    orientation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))),
                     joints=JointState(name=list(G1_JOINT_NAMES), position=[float(v) for v in kf.joints]))
        if kf.desired_foot_xy is not None:
            m.desired_foot_position = Point(x=float(kf.desired_foot_xy[0]), y=float(kf.desired_foot_xy[1]), z=0.0)
        m.contacts = [Contact(limb=c.limb, object_id=c.object_id,
                              position=Point(x=float(c.position[0]), y=float(c.position[1]), z=float(c.position[2])),
                              normal=Vector3(x=float(c.normal[0]), y=float(c.normal[1]), z=float(c.normal[2])),
                              confidence=1.0) for c in kf.contacts]
        out.keyframes.append(m)
    return out
