"""Pinhole camera and rigid pose helpers."""
from __future__ import annotations

import numpy as np

from lomanip_perception.datatypes import PinholeCamera, RigidPose


def test_backproject_project_round_trip():
    cam = PinholeCamera.from_fovy(640, 480, 55.0)
    rng = np.random.default_rng(0)
    u, v, z = rng.uniform(0, 640, 50), rng.uniform(0, 480, 50), rng.uniform(0.5, 5.0, 50)
    p = cam.backproject(u, v, z)
    assert np.allclose(p[:, 2], z) and np.allclose(cam.project(p), np.column_stack([u, v]))


def test_paper_heuristic_intrinsics():
    cam = PinholeCamera.paper_heuristic(1024, 1024)
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (1024.0, 1024.0, 512.0, 512.0)
    assert np.allclose(cam.K, [[1024, 0, 512], [0, 1024, 512], [0, 0, 1]])


def test_rigid_pose_inverse():
    c, s = np.cos(0.7), np.sin(0.7)
    pose = RigidPose(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), np.array([1.0, -2.0, 0.5]))
    p = np.random.default_rng(1).normal(size=(10, 3))
    assert np.allclose(pose.inverse_apply(pose.apply(p)), p)
    assert np.allclose(RigidPose.identity().apply(p), p)
