"""SVD (Umeyama), RANSAC, ICP, cleaning and lifting on point clouds with known answers."""
from __future__ import annotations

import numpy as np

from lomanip_perception import geometry as geo
from lomanip_perception.datatypes import PinholeCamera, RigidPose
from lomanip_perception.synthetic.objects import make_object
from lomanip_sim import frames


def _random_similarity(rng, s=1.15):
    R = frames.quat_to_matrix(frames.axis_angle_to_quat(rng.normal(size=3), 0.9))
    return s, R, rng.normal(size=3)


def test_umeyama_recovers_similarity_and_rigid():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(40, 3))
    s, R, t = _random_similarity(rng)
    dst = s * src @ R.T + t
    s1, R1, t1 = geo.umeyama(src, dst, with_scale=True)
    assert abs(s1 - s) < 1e-9 and np.allclose(R1, R) and np.allclose(t1, t)
    s2, R2, _ = geo.umeyama(src, src @ R.T + t, with_scale=False)
    assert s2 == 1.0 and np.allclose(R2, R) and np.linalg.det(R2) > 0
    sb, Rb, tb = geo.umeyama_batch(np.stack([src[:5], src[5:10]]), np.stack([dst[:5], dst[5:10]]), True)
    assert np.allclose(sb, s) and np.allclose(Rb, R) and np.allclose(tb, t)


def test_ransac_survives_half_outliers():
    rng = np.random.default_rng(1)
    src = rng.uniform(-0.3, 0.3, (100, 3))
    s, R, t = _random_similarity(rng, 0.9)
    dst = s * src @ R.T + t + rng.normal(0, 0.003, src.shape)
    bad = rng.random(100) < 0.5
    dst[bad] = rng.uniform(-0.3, 0.3, (bad.sum(), 3)) + t
    s1, R1, t1, inl = geo.ransac_transform(src, dst, rng, 256, 0.05, True)
    assert abs(s1 - s) < 0.02 and np.degrees(np.arccos((np.trace(R1.T @ R) - 1) / 2)) < 2.0
    assert inl[~bad].mean() > 0.9 and inl[bad].mean() < 0.1
    assert geo.ransac_transform(src[:2], dst[:2], rng, 10, 0.05, True) is None


def test_icp_refines_a_perturbed_alignment_and_scores_overlap():
    rng = np.random.default_rng(2)
    box = make_object("b", "box", (0.4, 0.3, 0.3), (1, 0, 0, 1), (0, 0, 0), 0.0)
    cloud = box.sample_surface(0.01, rng)
    R = frames.quat_to_matrix(frames.axis_angle_to_quat([0.2, 0.1, 1.0], 0.6))
    t = np.array([0.5, -0.2, 0.1])
    moved = cloud @ R.T + t
    init = geo.to_matrix(1.0, frames.quat_to_matrix(frames.axis_angle_to_quat([0.2, 0.1, 1.0], 0.5)), t + 0.03)
    T = geo.icp(geo.to_o3d(cloud), geo.to_o3d(moved), init, [0.08, 0.04, 0.02], False, 30)
    s, R1, t1 = geo.from_matrix(T)
    assert abs(s - 1) < 1e-6 and np.allclose(R1, R, atol=0.01) and np.allclose(t1, t, atol=0.005)
    good = geo.overlap_score(geo.to_o3d(cloud), geo.to_o3d(moved), T, 0.01)
    poor = geo.overlap_score(geo.to_o3d(cloud), geo.to_o3d(moved), init, 0.01)
    assert good > 0.9 and poor < good
    f, rmse = geo.fitness_rmse(geo.to_o3d(cloud), geo.to_o3d(moved), T, 0.01)
    assert f > 0.9 and rmse < 0.005


def test_clean_cloud_and_lift_mask():
    rng = np.random.default_rng(3)
    pts = np.vstack([rng.normal(0, 0.05, (3000, 3)), rng.uniform(2, 3, (5, 3))])
    out = geo.clean_cloud(pts, 0.01)
    assert np.all(np.linalg.norm(out, axis=1) < 1.0) and len(out) < len(pts)
    cam = PinholeCamera.from_fovy(40, 30, 60.0)
    depth = np.full((30, 40), 2.0, np.float32)
    depth[0, :] = np.nan
    depth[1, :] = np.inf
    mask = np.ones((30, 40), bool)
    p, uv = geo.lift_mask(depth, cam, mask, RigidPose(np.eye(3), np.array([0, 0, 1.0])))
    assert len(p) == 28 * 40 and np.allclose(p[:, 2], 3.0) and uv.min(0)[1] == 2
    m = np.zeros((30, 40), bool)
    m[5:25, 5:35] = True
    assert geo.erode(m, 2).sum() == 16 * 26
