"""Point-cloud geometry for contact transfer: lifting, cleaning, SVD (Umeyama), RANSAC, ICP.

numpy + open3d (KD-trees, voxel grid, statistical outlier removal, ICP); no ROS.
"""
from __future__ import annotations

import cv2
import numpy as np
import open3d as o3d

from .datatypes import PinholeCamera, RigidPose

o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)


def erode(mask: np.ndarray, px: int) -> np.ndarray:
    """Erode a mask by ``px`` pixels (drops the depth discontinuities at object borders)."""
    if px <= 0:
        return mask.astype(bool)
    k = np.ones((2 * px + 1, 2 * px + 1), np.uint8)
    out = cv2.erode(mask.astype(np.uint8), k).astype(bool)
    return out if out.sum() >= 20 else mask.astype(bool)


def lift_mask(depth: np.ndarray, camera: PinholeCamera, mask: np.ndarray, pose: RigidPose | None = None,
              max_depth: float = 20.0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """3D points (camera frame, or world with ``pose``) and their pixels (u, v) for masked pixels
    with a finite, positive depth below ``max_depth``."""
    v, u = np.nonzero(mask)
    z = depth[v, u].astype(float)
    ok = np.isfinite(z) & (z > 0) & (z < max_depth)
    u, v, z = u[ok], v[ok], z[ok]
    pts = camera.backproject(u, v, z)
    if pose is not None:
        pts = pose.apply(pts)
    return pts, np.column_stack([u, v])


def to_o3d(points: np.ndarray) -> o3d.geometry.PointCloud:
    pc = o3d.geometry.PointCloud()
    pc.points = o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64))
    return pc


def clean_cloud(points: np.ndarray, voxel: float, nb_neighbors: int = 16, std_ratio: float = 2.0) -> np.ndarray:
    """Voxel downsampling, then statistical outlier removal."""
    if len(points) == 0:
        return points
    pc = to_o3d(points).voxel_down_sample(max(voxel, 1e-4))
    if len(pc.points) > nb_neighbors + 1:
        pc, _ = pc.remove_statistical_outlier(nb_neighbors=nb_neighbors, std_ratio=std_ratio)
    return np.asarray(pc.points)


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = False,
            weights: np.ndarray | None = None) -> tuple[float, np.ndarray, np.ndarray]:  # fmt: skip
    """s, R, t minimising sum w |s R src + t - dst|^2 (SVD; Umeyama 1991). Rigid when not with_scale."""
    w = np.ones(len(src)) if weights is None else np.asarray(weights, float)
    w = w / w.sum()
    mu_s, mu_d = w @ src, w @ dst
    xs, xd = src - mu_s, dst - mu_d
    C = (xd * w[:, None]).T @ xs
    U, S, Vt = np.linalg.svd(C)
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / max(w @ (xs ** 2).sum(1), 1e-12)) if with_scale else 1.0
    return s, R, mu_d - s * R @ mu_s


def umeyama_batch(src: np.ndarray, dst: np.ndarray, with_scale: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised Umeyama for K hypotheses of n pairs each: src, dst (K, n, 3)."""
    mu_s, mu_d = src.mean(1), dst.mean(1)
    xs, xd = src - mu_s[:, None], dst - mu_d[:, None]
    C = np.einsum("kni,knj->kij", xd, xs) / src.shape[1]
    U, S, Vt = np.linalg.svd(C)
    sign = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    sign[sign == 0] = 1.0
    D = np.tile(np.eye(3), (len(src), 1, 1))
    D[:, 2, 2] = sign
    R = U @ D @ Vt
    if with_scale:
        var = (xs ** 2).sum((1, 2)) / src.shape[1]
        s = (S * D.diagonal(axis1=1, axis2=2)).sum(1) / np.maximum(var, 1e-12)
    else:
        s = np.ones(len(src))
    t = mu_d - s[:, None] * np.einsum("kij,kj->ki", R, mu_s)
    return s, R, t


def ransac_transform(src: np.ndarray, dst: np.ndarray, rng: np.random.Generator, hypotheses: int,
                     threshold: float, with_scale: bool, scale_range=(0.6, 1.6)):  # fmt: skip
    """Robust SVD over correspondences (src[i] -> dst[i]): best 3-pair hypothesis by inlier count,
    refitted on its inliers. Returns (s, R, t, inlier mask) or None."""
    n = len(src)
    if n < 3:
        return None
    idx = np.array([rng.choice(n, 3, replace=False) for _ in range(hypotheses)])
    s, R, t = umeyama_batch(src[idx], dst[idx], with_scale)
    ok = (s > scale_range[0]) & (s < scale_range[1])
    if not ok.any():
        return None
    s, R, t = s[ok], R[ok], t[ok]
    pred = s[:, None, None] * np.einsum("kij,nj->kni", R, src) + t[:, None, :]
    res = np.linalg.norm(pred - dst[None], axis=2)
    counts = (res < threshold).sum(1)
    k = int(np.argmax(counts))
    inl = res[k] < threshold
    if inl.sum() < 3:
        return None
    best = (float(s[k]), R[k], t[k], inl)
    # local optimisation: refit on the inliers with a tightening threshold
    for thr in (threshold, threshold / 2, threshold / 4):
        if inl.sum() < 6:
            break
        s1, R1, t1 = umeyama(src[inl], dst[inl], with_scale)
        if not (scale_range[0] < s1 < scale_range[1]):
            break
        res1 = np.linalg.norm(s1 * src @ R1.T + t1 - dst, axis=1)
        best = (s1, R1, t1, inl)
        inl = res1 < thr
    return best


def to_matrix(s: float, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = s * R
    T[:3, 3] = t
    return T


def from_matrix(T: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    A = T[:3, :3]
    s = float(np.cbrt(np.linalg.det(A)))
    return s, A / s, T[:3, 3].copy()


def icp(src: o3d.geometry.PointCloud, dst: o3d.geometry.PointCloud, init: np.ndarray, max_dists,
        with_scale: bool, iterations: int = 30) -> np.ndarray:  # fmt: skip
    """Coarse-to-fine point-to-point ICP (similarity with ``with_scale``)."""
    reg = o3d.pipelines.registration
    T = init
    est = reg.TransformationEstimationPointToPoint(with_scale)
    for d in max_dists:
        crit = reg.ICPConvergenceCriteria(relative_fitness=1e-4, relative_rmse=1e-4, max_iteration=iterations)
        res = reg.registration_icp(src, dst, d, T, est, crit)
        if len(res.correspondence_set) >= 3:
            T = res.transformation
    return T


def fitness(src: o3d.geometry.PointCloud, dst: o3d.geometry.PointCloud, T: np.ndarray, threshold: float) -> float:
    """Fraction of transformed source points with a target point within ``threshold``."""
    return float(o3d.pipelines.registration.evaluate_registration(src, dst, threshold, T).fitness)


def fitness_rmse(src, dst, T: np.ndarray, threshold: float) -> tuple[float, float]:
    r = o3d.pipelines.registration.evaluate_registration(src, dst, threshold, T)
    return float(r.fitness), float(r.inlier_rmse)


def overlap_score(src: o3d.geometry.PointCloud, dst: o3d.geometry.PointCloud, T: np.ndarray,
                  threshold: float) -> float:  # fmt: skip
    """Geometric overlap of a transform: sqrt(fraction of transformed source points near the target
    x fraction of target points near the transformed source) (symmetric, so collapsing the source
    onto a small patch by scaling cannot score well)."""
    reg = o3d.pipelines.registration
    a = reg.evaluate_registration(src, dst, threshold, T).fitness
    b = reg.evaluate_registration(dst, src, threshold, np.linalg.inv(T)).fitness
    return float(np.sqrt(a * b))
