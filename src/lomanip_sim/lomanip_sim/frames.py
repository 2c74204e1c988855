"""Quaternion and frame conventions: the ONE place where they are converted.

Why: three libraries meet in lomanip and disagree on quaternion order.

* MuJoCo (``qpos``, ``xquat``, ``MjSpec.quat``): ``(w, x, y, z)``.
* ROS (``geometry_msgs/Quaternion``): ``(x, y, z, w)``.
* Pinocchio (the 4 quaternion entries of a free-flyer ``q``, ``pin.Quaternion.coeffs()``):
  ``(x, y, z, w)``.

All functions take and return numpy arrays, use unit quaternions, and never import mujoco or
rclpy. Rotation matrices act on column vectors (``v_world = R @ v_body``).

Camera frames: MuJoCo cameras look along their ``-z`` axis with ``+y`` up and ``+x`` right; the ROS
optical frame looks along ``+z`` with ``+y`` down and ``+x`` right. ``R_MJCAM_TO_OPTICAL`` maps
between them (a rotation of pi about the camera x axis).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

ArrayLike = Sequence[float] | np.ndarray

#: Rotation taking vectors expressed in the ROS optical frame into the MuJoCo camera frame
#: (x stays, y and z flip). It is its own inverse.
R_MJCAM_TO_OPTICAL = np.diag([1.0, -1.0, -1.0])


class FrameError(ValueError):
    """A quaternion or rotation had the wrong shape or zero norm."""


def _as_quat(q: ArrayLike) -> np.ndarray:
    arr = np.asarray(q, dtype=float).reshape(-1)
    if arr.shape != (4,):
        raise FrameError(f"expected a quaternion of 4 numbers, got shape {np.shape(q)}")
    n = np.linalg.norm(arr)
    if not np.isfinite(n) or n < 1e-12:
        raise FrameError(f"quaternion has zero or non-finite norm: {arr}")
    return arr / n


def wxyz_to_xyzw(q: ArrayLike) -> np.ndarray:
    """MuJoCo (w,x,y,z) -> ROS/Pinocchio (x,y,z,w), normalised."""
    a = _as_quat(q)
    return np.array([a[1], a[2], a[3], a[0]])


def xyzw_to_wxyz(q: ArrayLike) -> np.ndarray:
    """ROS/Pinocchio (x,y,z,w) -> MuJoCo (w,x,y,z), normalised."""
    a = _as_quat(q)
    return np.array([a[3], a[0], a[1], a[2]])


# Named aliases so call sites say which library they talk to.
mujoco_to_ros_quat = wxyz_to_xyzw
ros_to_mujoco_quat = xyzw_to_wxyz
mujoco_to_pinocchio_quat = wxyz_to_xyzw
pinocchio_to_mujoco_quat = xyzw_to_wxyz


def mujoco_qpos_to_pinocchio(qpos: ArrayLike) -> np.ndarray:
    """Free-flyer configuration: MuJoCo [p, (w,x,y,z), joints] -> Pinocchio [p, (x,y,z,w), joints].

    Joint order is identical for g1.xml loaded by MuJoCo and pinocchio.buildModelFromMJCF.
    """
    q = np.asarray(qpos, dtype=float).copy()
    q[3:7] = wxyz_to_xyzw(q[3:7])
    return q


def pinocchio_q_to_mujoco(q: ArrayLike) -> np.ndarray:
    """Inverse of :func:`mujoco_qpos_to_pinocchio`."""
    out = np.asarray(q, dtype=float).copy()
    out[3:7] = xyzw_to_wxyz(out[3:7])
    return out


def quat_to_matrix(q_wxyz: ArrayLike) -> np.ndarray:
    """Rotation matrix of a (w,x,y,z) quaternion."""
    w, x, y, z = _as_quat(q_wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(R: ArrayLike) -> np.ndarray:
    """(w,x,y,z) quaternion (w >= 0) of a rotation matrix (Shepperd's method)."""
    M = np.asarray(R, dtype=float)
    if M.shape != (3, 3):
        raise FrameError(f"expected a 3x3 rotation matrix, got shape {M.shape}")
    tr = np.trace(M)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array([0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s])
    elif M[0, 0] > M[1, 1] and M[0, 0] > M[2, 2]:
        s = 2.0 * np.sqrt(1.0 + M[0, 0] - M[1, 1] - M[2, 2])
        q = np.array([(M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s, (M[0, 2] + M[2, 0]) / s])
    elif M[1, 1] > M[2, 2]:
        s = 2.0 * np.sqrt(1.0 + M[1, 1] - M[0, 0] - M[2, 2])
        q = np.array([(M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s, (M[1, 2] + M[2, 1]) / s])
    else:
        s = 2.0 * np.sqrt(1.0 + M[2, 2] - M[0, 0] - M[1, 1])
        q = np.array([(M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s, (M[1, 2] + M[2, 1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def quat_multiply(a_wxyz: ArrayLike, b_wxyz: ArrayLike) -> np.ndarray:
    """Hamilton product a*b of (w,x,y,z) quaternions (apply b first, then a)."""
    w1, x1, y1, z1 = _as_quat(a_wxyz)
    w2, x2, y2, z2 = _as_quat(b_wxyz)
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def quat_conjugate(q_wxyz: ArrayLike) -> np.ndarray:
    """Inverse rotation of a unit (w,x,y,z) quaternion."""
    q = _as_quat(q_wxyz)
    return np.array([q[0], -q[1], -q[2], -q[3]])


def axis_angle_to_quat(axis: ArrayLike, angle: float) -> np.ndarray:
    """(w,x,y,z) quaternion rotating by ``angle`` (rad) about ``axis``."""
    a = np.asarray(axis, dtype=float)
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise FrameError("rotation axis has zero norm")
    a = a / n
    return np.concatenate([[np.cos(angle / 2.0)], np.sin(angle / 2.0) * a])


def yaw_to_quat(yaw: float) -> np.ndarray:
    """(w,x,y,z) quaternion of a rotation by ``yaw`` about world z."""
    return np.array([np.cos(yaw / 2.0), 0.0, 0.0, np.sin(yaw / 2.0)])


def quat_to_yaw(q_wxyz: ArrayLike) -> float:
    """Yaw (rad, z-y-x Euler convention) of a (w,x,y,z) quaternion."""
    w, x, y, z = _as_quat(q_wxyz)
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def quat_to_rpy(q_wxyz: ArrayLike) -> np.ndarray:
    """Roll, pitch, yaw (rad; R = Rz(yaw) Ry(pitch) Rx(roll)) of a (w,x,y,z) quaternion."""
    w, x, y, z = _as_quat(q_wxyz)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.array([roll, pitch, yaw])


def rpy_to_quat(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """(w,x,y,z) quaternion of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    qx = axis_angle_to_quat([1, 0, 0], roll)
    qy = axis_angle_to_quat([0, 1, 0], pitch)
    qz = axis_angle_to_quat([0, 0, 1], yaw)
    return quat_multiply(qz, quat_multiply(qy, qx))


def tilt_angle(q_wxyz: ArrayLike) -> float:
    """Angle (rad) between the body z axis and world z: 0 when upright."""
    R = quat_to_matrix(q_wxyz)
    return float(np.arccos(np.clip(R[2, 2], -1.0, 1.0)))


def look_at_mujoco_camera_quat(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0, 0, 1)) -> np.ndarray:
    """(w,x,y,z) orientation of a MuJoCo camera at ``eye`` looking at ``target``.

    The MuJoCo camera looks along its -z axis, x points right, y up in the image.
    """
    eye = np.asarray(eye, dtype=float)
    f = np.asarray(target, dtype=float) - eye
    if np.linalg.norm(f) < 1e-9:
        raise FrameError("camera eye and target coincide")
    f /= np.linalg.norm(f)
    right = np.cross(f, np.asarray(up, dtype=float))
    if np.linalg.norm(right) < 1e-9:
        raise FrameError("camera viewing direction is parallel to 'up'")
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, f)
    R = np.column_stack([right, cam_up, -f])
    return matrix_to_quat(R)


def mujoco_camera_to_optical(pos: ArrayLike, R_mjcam: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """World pose of the ROS optical frame from a MuJoCo camera world pose.

    Returns (position, rotation matrix); the position is shared.
    """
    R = np.asarray(R_mjcam, dtype=float) @ R_MJCAM_TO_OPTICAL
    return np.asarray(pos, dtype=float).copy(), R


def transform_point(pos: ArrayLike, q_wxyz: ArrayLike, p_local: ArrayLike) -> np.ndarray:
    """World coordinates of a point given in a frame with pose (pos, q_wxyz)."""
    return np.asarray(pos, dtype=float) + quat_to_matrix(q_wxyz) @ np.asarray(p_local, dtype=float)
