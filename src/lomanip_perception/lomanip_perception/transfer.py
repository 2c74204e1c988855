"""Contact transfer (paper Sec. III-A2): from a generated image R_g to the simulated scene R_s.

For one object:
 1. lift its mask in R_g with the estimated depth D_g and the paper's heuristic intrinsics
    (f = image resolution, principal point = half of it), and its mask in R_s with the true depth
    and intrinsics into the world frame; clean both (mask erosion, voxel grid, statistical outliers);
 2. sample points on the R_g mask and ask the semantic matcher for a pool of the top-N candidate
    correspondences in R_s per point;
 3. geometry-aware search, ``iterations`` times (10, as in the paper): draw one candidate per
    sampled point from its pool (the top-1 on the first iteration, then by matcher score), solve
    the rigid (or, optionally, similarity) transform with SVD inside RANSAC over that candidate set,
    refine it with ICP between the two clouds, and score the geometric overlap; the transform with
    the best overlap wins;
 4. apply it to the lifted hand/foot points and project each onto the closest surface of the scene
    object (its primitives).

The geometry-unaware variant (the paper's ablation, Sec. V-B) maps each contact pixel with the
matcher's top-1 correspondence and lifts it with the scene depth: semantic matches only.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from . import geometry as geo
from .datatypes import MatchPool, PerceptionImage, PinholeCamera
from .errors import CONTACT_TRANSFER_FAILED, PerceptionError
from .scene import ObjectGeometry

METHODS = ("geometry_aware", "geometry_unaware")


@dataclass(frozen=True)
class TransferConfig:
    method: str = "geometry_aware"
    iterations: int = 10
    samples: int = 96
    top_n: int = 5
    similarity: bool = True
    ransac_hypotheses: int = 256
    inlier_threshold: float = 0.12  # x scene object diameter (RANSAC; then tightened to a quarter)
    icp_target: str = "object_model"  # "object_model" (scene object's primitives) | "scene_cloud" (R_s)
    overlap_threshold: float = 0.025  # x scene object diameter
    voxel_fraction: float = 0.03  # voxel size as a fraction of the object diameter
    icp_iterations: int = 10
    mask_erosion_px: int = 2
    min_points: int = 30
    seed: int = 0

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"transfer method must be one of {METHODS}, got {self.method!r}")
        if self.icp_target not in ("object_model", "scene_cloud"):
            raise ValueError(f"icp_target must be 'object_model' or 'scene_cloud', got {self.icp_target!r}")
        if self.iterations < 1 or self.samples < 3 or self.top_n < 1:
            raise ValueError("transfer needs iterations >= 1, samples >= 3, top_n >= 1")


@dataclass
class ObjectTransfer:
    """The transform mapping R_g camera-frame points of one object to the world, and how it was found."""

    object_id: str
    scale: float
    R: np.ndarray
    t: np.ndarray
    overlap: float
    best_iteration: int
    iteration_scores: list[float] = field(default_factory=list)
    n_points_generated: int = 0
    n_points_scene: int = 0
    seconds: float = 0.0
    method: str = "geometry_aware"

    def apply(self, p: np.ndarray) -> np.ndarray:
        return self.scale * np.atleast_2d(p) @ self.R.T + self.t


def _fail(label: str, what: str) -> PerceptionError:
    return PerceptionError(CONTACT_TRANSFER_FAILED, f"{label}: {what}")


class ContactTransfer:
    def __init__(self, config: TransferConfig | None = None):
        self.config = config or TransferConfig()

    # -------------------------------------------------------------------------------- helpers
    def _clouds(self, gen_depth, gen_cam, gen_mask, scene: PerceptionImage, scene_mask, obj: ObjectGeometry, label):
        cfg = self.config
        mg = geo.erode(gen_mask, cfg.mask_erosion_px)
        ms = geo.erode(scene_mask, cfg.mask_erosion_px)
        pg, uvg = geo.lift_mask(gen_depth, gen_cam, mg)
        ps, _ = geo.lift_mask(scene.depth, scene.camera, ms, scene.camera_pose)
        if len(pg) < cfg.min_points:
            raise _fail(label, f"only {len(pg)} valid depth points on the {obj.object_class} in the generated image")
        if len(ps) < cfg.min_points:
            raise _fail(label, f"only {len(ps)} valid depth points on {obj.id!r} in the scene image (NaN/inf depth?)")
        diam = obj.diameter
        diam_g = float(np.linalg.norm(np.percentile(pg, 98, 0) - np.percentile(pg, 2, 0)))
        cg = geo.clean_cloud(pg, cfg.voxel_fraction * diam_g)
        cs = geo.clean_cloud(ps, cfg.voxel_fraction * diam)
        return pg, uvg, mg, cg, cs, diam

    def _sample_queries(self, uvg: np.ndarray, rng) -> np.ndarray:
        n = min(self.config.samples, len(uvg))
        return uvg[rng.choice(len(uvg), n, replace=False)]

    # -------------------------------------------------------------------------------- aware
    def estimate(self, gen: PerceptionImage, gen_depth: np.ndarray, gen_cam: PinholeCamera, gen_mask: np.ndarray,
                 scene: PerceptionImage, scene_mask: np.ndarray, obj: ObjectGeometry, matcher,
                 label: str = "") -> ObjectTransfer:  # fmt: skip
        """The transform from R_g camera coordinates to the world for ``obj`` (method per config)."""
        cfg = self.config
        t0 = time.perf_counter()
        rng = np.random.default_rng([cfg.seed, int(getattr(gen.ground_truth, "seed", 0)) & 0xFFFFFFFF])
        pg, uvg, mg, cg, cs, diam = self._clouds(gen_depth, gen_cam, gen_mask, scene, scene_mask, obj, label)
        queries = self._sample_queries(uvg, rng)
        pool = matcher.match(gen, mg, queries, scene, scene_mask, cfg.top_n)
        src = gen_cam.backproject(pool.query_uv[:, 0], pool.query_uv[:, 1], gen_depth[pool.query_uv[:, 1], pool.query_uv[:, 0]])
        cu, cv = pool.candidates_uv[..., 0], pool.candidates_uv[..., 1]
        zc = scene.depth[cv, cu].astype(float)
        valid = np.isfinite(zc) & (zc > 0)
        dst = scene.camera_pose.apply(scene.camera.backproject(cu.ravel(), cv.ravel(), np.where(valid, zc, 1.0).ravel()))
        dst = dst.reshape(*cu.shape, 3)
        if cfg.method == "geometry_unaware":
            top = valid[:, 0]
            if top.sum() < 3:
                raise _fail(label, "fewer than 3 valid semantic matches")
            s, R, t = geo.umeyama(src[top], dst[top, 0], cfg.similarity)
            return ObjectTransfer(obj.id, s, R, t, 0.0, 0, [], len(pg), len(cs), time.perf_counter() - t0, cfg.method)
        src_pc = geo.to_o3d(cg)
        if cfg.icp_target == "object_model":
            dst_pc = geo.to_o3d(obj.sample_surface(cfg.voxel_fraction * diam, rng))
        else:
            dst_pc = geo.to_o3d(cs)
        thr = cfg.inlier_threshold * diam
        best, scores = None, []
        weights = np.where(valid, np.maximum(pool.scores, 1e-3), 0.0)
        for it in range(cfg.iterations):
            if it == 0:
                choice = np.argmax(weights > 0, axis=1)
            else:
                p = weights / np.maximum(weights.sum(1, keepdims=True), 1e-12)
                choice = (p.cumsum(1) > rng.random((len(p), 1))).argmax(1)
            rows = np.arange(len(choice))
            ok = valid[rows, choice]
            if ok.sum() < 3:
                scores.append(0.0)
                continue
            fit = geo.ransac_transform(src[ok], dst[rows, choice][ok], rng, cfg.ransac_hypotheses, thr, cfg.similarity)
            if fit is None:
                scores.append(0.0)
                continue
            s, R, t, _ = fit
            # ICP is rigid, at the scale the semantic correspondences gave (a free scale in ICP
            # between partial views shrinks the source onto a patch of the target)
            src_scaled = geo.to_o3d(cg * s)
            T = geo.icp(src_scaled, dst_pc, geo.to_matrix(1.0, R, t), [0.06 * diam, 0.03 * diam, 0.015 * diam],
                        False, cfg.icp_iterations)  # fmt: skip
            T = T @ np.diag([s, s, s, 1.0])
            tau = cfg.overlap_threshold * diam
            if cfg.icp_target == "object_model":
                fit_g, rmse = geo.fitness_rmse(src_pc, dst_pc, T, tau)
                overlap = fit_g * (1.0 - 0.5 * rmse / tau)
            else:
                overlap = geo.overlap_score(src_pc, dst_pc, T, tau)
            # tie-break between geometrically equivalent alignments (symmetric objects): the share
            # of this candidate set's semantic matches the transform agrees with
            s3, R3, t3 = geo.from_matrix(T)
            agree = np.linalg.norm(s3 * src[ok] @ R3.T + t3 - dst[rows, choice][ok], axis=1) < 0.5 * thr
            score = overlap + 0.2 * float(agree.mean())
            scores.append(score)
            if best is None or score > best[0]:
                best = (score, T, it)
        if best is None:
            raise _fail(label, f"no transform found for {obj.id!r} in {cfg.iterations} iterations")
        s, R, t = geo.from_matrix(best[1])
        return ObjectTransfer(obj.id, s, R, t, best[0], best[2], scores, len(pg), len(cs), time.perf_counter() - t0,
                              cfg.method)  # fmt: skip

    # -------------------------------------------------------------------------------- unaware contacts
    def unaware_points(self, gen: PerceptionImage, gen_mask: np.ndarray, contact_uv: np.ndarray,
                       scene: PerceptionImage, scene_mask: np.ndarray, matcher, label: str = "") -> np.ndarray:  # fmt: skip
        """Geometry-unaware contacts: nearest object pixel of each contact pixel in R_g -> matcher
        top-1 in R_s -> lifted with the scene depth (world)."""
        v, u = np.nonzero(gen_mask)
        if len(u) == 0:
            raise _fail(label, "empty object mask in the generated image")
        uv = np.column_stack([u, v])
        q = []
        for c in np.atleast_2d(contact_uv):
            q.append(uv[np.argmin(((uv - c) ** 2).sum(1))])
        pool: MatchPool = matcher.match(gen, gen_mask, np.array(q), scene, scene_mask, 1)
        cu, cv = pool.candidates_uv[:, 0, 0], pool.candidates_uv[:, 0, 1]
        z = scene.depth[cv, cu].astype(float)
        if not np.all(np.isfinite(z)):
            raise _fail(label, "a semantic match fell on a pixel without depth")
        return scene.camera_pose.apply(scene.camera.backproject(cu, cv, z))


#: approximate depth of the body surface in front of each keypoint (m); a mesh-based pose estimator
#: (WHAM/SMPL) knows it exactly. Used to compare keypoint depths with the depth map.
SURFACE_OFFSET = {"pelvis": 0.10, "spine": 0.11, "neck": 0.05, "head": 0.09, "shoulder": 0.05, "elbow": 0.04,
                  "wrist": 0.03, "hand": 0.02, "hip": 0.08, "knee": 0.05, "ankle": 0.04, "heel": 0.04,
                  "toe": 0.04, "foot": 0.04}


def _offset(name: str) -> float:
    return SURFACE_OFFSET.get(name.split("_", 1)[-1], 0.04)


def lift_keypoints(pose, names: list[str], gen_depth: np.ndarray, gen_cam: PinholeCamera,
                   max_depth: float = 20.0) -> np.ndarray:  # fmt: skip
    """3D points (R_g camera frame, heuristic intrinsics) of named 2D keypoints.

    A visible keypoint takes the estimated depth at its pixel; an occluded one takes the pose
    estimator's own depth rescaled to the depth map (median ratio over the visible keypoints), so
    a hand hidden behind the object is not lifted onto the object's front face."""
    H, W = gen_depth.shape
    uv = np.asarray(pose.uv, float)
    ui = np.clip(np.round(uv[:, 0]).astype(int), 0, W - 1)
    vi = np.clip(np.round(uv[:, 1]).astype(int), 0, H - 1)
    d_map = gen_depth[vi, ui].astype(float)
    z_pose = np.asarray(pose.xyz_camera, float)[:, 2]
    vis = (np.asarray(pose.visibility) > 0.5) & np.isfinite(d_map) & (d_map < max_depth) & (z_pose > 0)
    off = np.array([_offset(n) for n in pose.keypoint_names])
    ratio = float(np.median(d_map[vis] / np.maximum(z_pose[vis] - off[vis], 1e-3))) if vis.sum() >= 3 else 1.0
    out = []
    for n in names:
        i = pose.index(n)
        z_est = ratio * z_pose[i]
        z_vis = d_map[i] + ratio * off[i]
        z = z_vis if vis[i] and abs(z_vis - z_est) < 0.1 * z_est else z_est
        out.append(gen_cam.backproject(uv[i, 0], uv[i, 1], z))
    return np.array(out)
