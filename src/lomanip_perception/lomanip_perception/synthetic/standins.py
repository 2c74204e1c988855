"""'synthetic' stand-ins of the detector, segmenter, depth estimator, matcher and pose estimator.

They do not look at pixels: they read the ground truth attached to a PerceptionImage (the
synthetic generator's DemoGroundTruth for R_g; SceneGroundTruth, the scene's known object geometry,
for R_s) and corrupt it in the ways the paper's models fail, with the corruption configurable:

* depth: a global scale error (sign random per image) and multiplicative Gaussian noise;
* matcher: a top-N candidate pool per query point; with probability ``outlier_rate`` the best
  candidate is wrong: a left/right-symmetric flip (the failure the paper describes) or a random
  point on the object, and the right match may be missing from the pool altogether;
* pose: Gaussian noise on 2D keypoints (pixels) and 3D keypoints (metres);
* segmenter: mask boundaries eroded/dilated by a few pixels; detector: box jitter.

Every stand-in's ``name`` is "synthetic"; logs and messages say so.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..datatypes import Detection, HumanPose2D3D, MatchPool, PerceptionImage
from ..errors import INVALID_REQUEST, PerceptionError
from ..registry import register
from ..scene import ObjectGeometry
from .generator import PERSON, DemoGroundTruth
from .human import KEYPOINTS

LIMB_JOINTS = ("left_hip_pitch_joint", "left_knee_joint", "right_hip_pitch_joint", "right_knee_joint",
               "waist_pitch_joint", "left_shoulder_pitch_joint", "left_elbow_joint", "right_shoulder_pitch_joint",
               "right_elbow_joint")  # fmt: skip


@dataclass
class SceneGroundTruth:
    """What the synthetic stand-ins may know about a simulated scene image: its objects' geometry.
    Per-pixel labels come from lifting the true depth and testing distance to each object."""

    objects: list[ObjectGeometry]
    tolerance: float = 0.015
    _labels: np.ndarray | None = field(default=None, repr=False)

    def labels(self, image: PerceptionImage) -> np.ndarray:
        """(H, W) int16: -1 nothing, k = index of the object within tolerance of the pixel's point."""
        if self._labels is not None and self._labels.shape == image.depth.shape:
            return self._labels
        depth = image.depth
        H, W = depth.shape
        out = np.full((H, W), -1, np.int16)
        valid = np.isfinite(depth) & (depth > 0)
        v, u = np.nonzero(valid)
        if len(u):
            pts = image.camera_pose.apply(image.camera.backproject(u, v, depth[v, u]))
            best = np.full(len(u), np.inf)
            lab = np.full(len(u), -1, np.int16)
            for k, obj in enumerate(self.objects):
                # only points inside the object's (padded) bounding box can be on it
                c, h = obj.bbox_local()
                near = np.all(np.abs(obj.to_local(pts) - c) <= h + self.tolerance, axis=1)
                idx = np.nonzero(near)[0]
                if len(idx) == 0:
                    continue
                sd, _, _ = obj.signed_distance(pts[idx])
                hit = (sd < self.tolerance) & (sd < best[idx])
                best[idx[hit]] = sd[hit]
                lab[idx[hit]] = k
            out[v, u] = lab
        self._labels = out
        return out


def _instances(image: PerceptionImage, label: str) -> list[tuple[str, np.ndarray, ObjectGeometry | None]]:
    """(name, mask, geometry) of every ground-truth instance of class ``label`` in the image."""
    gt = image.ground_truth
    if isinstance(gt, DemoGroundTruth):
        if label == "person":
            return [("person", gt.mask("person"), None)] if gt.human_present else []
        return [(n, gt.mask(n), gt.objects[n]) for n in gt.names_of_class(label)]
    if isinstance(gt, SceneGroundTruth):
        if image.depth is None or image.camera is None or image.camera_pose is None:
            raise PerceptionError(INVALID_REQUEST, "synthetic stand-ins need the scene image's depth, intrinsics and pose")
        labs = gt.labels(image)
        return [(o.id, labs == k, o) for k, o in enumerate(gt.objects) if o.object_class == label]
    raise PerceptionError(INVALID_REQUEST, "the 'synthetic' model backends only work on synthetic demonstrations and "
                          "simulated scene images (no ground truth attached to this image); configure real model backends")


def _world_points(image: PerceptionImage, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    gt = image.ground_truth
    if isinstance(gt, DemoGroundTruth):
        return gt.world_points(u, v)
    return image.camera_pose.apply(image.camera.backproject(u, v, image.depth[v, u]))


def _rng(seed: int, image: PerceptionImage, salt: int) -> np.random.Generator:
    gt_seed = getattr(image.ground_truth, "seed", 0)
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, int(gt_seed) & 0xFFFFFFFF, salt])


class SyntheticDetector:
    name = "synthetic"

    def __init__(self, box_jitter_px: float = 2.0, min_pixels: int = 40, seed: int = 0):
        self.box_jitter_px, self.min_pixels, self.seed = float(box_jitter_px), int(min_pixels), int(seed)

    def detect(self, image: PerceptionImage, labels) -> list[Detection]:
        rng = _rng(self.seed, image, 1)
        out = []
        for label in labels:
            for _, mask, _ in _instances(image, label):
                if mask.sum() < self.min_pixels:
                    continue
                v, u = np.nonzero(mask)
                box = np.array([u.min(), v.min(), u.max(), v.max()], float) + rng.normal(0, self.box_jitter_px, 4)
                out.append(Detection(label, tuple(float(x) for x in box), 0.9))
        return out


class SyntheticSegmenter:
    name = "synthetic"

    def __init__(self, boundary_noise_px: int = 1, seed: int = 0):
        self.boundary_noise_px, self.seed = int(boundary_noise_px), int(seed)

    def segment(self, image: PerceptionImage, detections) -> list[np.ndarray]:
        rng = _rng(self.seed, image, 2)
        masks = []
        for det in detections:
            x0, y0, x1, y1 = det.box
            box = np.zeros(image.rgb.shape[:2], bool)
            m = 4
            box[max(0, int(y0) - m):int(y1) + m + 1, max(0, int(x0) - m):int(x1) + m + 1] = True
            best, best_iou = np.zeros_like(box), 0.0
            for _, mask, _ in _instances(image, det.label):
                inter = (mask & box).sum()
                iou = inter / max(1, (mask | box).sum())
                if inter and iou > best_iou:
                    best, best_iou = mask & box, iou
            k = int(rng.integers(-self.boundary_noise_px, self.boundary_noise_px + 1)) if self.boundary_noise_px else 0
            if k and best.any():
                kernel = np.ones((2 * abs(k) + 1, 2 * abs(k) + 1), np.uint8)
                op = cv2.dilate if k > 0 else cv2.erode
                best = op(best.astype(np.uint8), kernel).astype(bool)
            masks.append(best)
        return masks


class SyntheticDepthEstimator:
    name = "synthetic"

    def __init__(self, scale_error: float = 0.10, noise: float = 0.01, random_sign: bool = True,
                 background_depth: float = 30.0, seed: int = 0):  # fmt: skip
        self.scale_error, self.noise = float(scale_error), float(noise)
        self.random_sign, self.background_depth, self.seed = bool(random_sign), float(background_depth), int(seed)

    def estimate(self, image: PerceptionImage) -> np.ndarray:
        gt = image.ground_truth
        if not isinstance(gt, DemoGroundTruth):
            if image.depth is not None:
                return image.depth
            raise PerceptionError(INVALID_REQUEST, "the synthetic depth estimator needs a synthetic demonstration image")
        rng = _rng(self.seed, image, 3)
        sign = rng.choice([-1.0, 1.0]) if self.random_sign else 1.0
        depth = gt.depth.astype(np.float64) * (1.0 + sign * self.scale_error)
        depth *= 1.0 + self.noise * rng.standard_normal(depth.shape)
        depth[~np.isfinite(depth)] = self.background_depth
        return depth.astype(np.float32)


class SyntheticMatcher:
    """Top-N semantic correspondences from canonical (bounding-box normalised) object coordinates."""

    name = "synthetic"

    def __init__(self, outlier_rate: float = 0.4, flip_fraction: float = 0.5, noise: float = 0.03,
                 true_in_pool_when_outlier: float = 0.6, max_target_pixels: int = 12000, seed: int = 0):  # fmt: skip
        if not 0.0 <= outlier_rate <= 1.0:
            raise ValueError("outlier_rate must be in [0, 1]")
        self.outlier_rate, self.flip_fraction, self.noise = float(outlier_rate), float(flip_fraction), float(noise)
        self.true_in_pool = float(true_in_pool_when_outlier)
        self.max_target_pixels, self.seed = int(max_target_pixels), int(seed)

    @staticmethod
    def _object_of(image: PerceptionImage, mask: np.ndarray) -> ObjectGeometry:
        gt = image.ground_truth
        best, best_n = None, 0
        classes = {o.object_class for o in (gt.objects.values() if isinstance(gt, DemoGroundTruth) else gt.objects)}
        for cls in classes:
            for _, m, geom in _instances(image, cls):
                n = int((m & mask).sum())
                if n > best_n:
                    best, best_n = geom, n
        if best is None:
            raise PerceptionError(INVALID_REQUEST, "synthetic matcher: the mask covers no known object")
        return best

    def match(self, source, source_mask, query_uv, target, target_mask, top_n: int) -> MatchPool:
        rng = _rng(self.seed, source, 4)
        q = np.asarray(query_uv, int)
        src_obj = self._object_of(source, source_mask)
        tgt_obj = self._object_of(target, target_mask)
        c_src = src_obj.canonical(_world_points(source, q[:, 0], q[:, 1]))
        tv, tu = np.nonzero(target_mask & np.isfinite(target.depth if target.depth is not None else 0.0))
        if len(tu) > self.max_target_pixels:
            keep = rng.choice(len(tu), self.max_target_pixels, replace=False)
            tu, tv = tu[keep], tv[keep]
        c_tgt = tgt_obj.canonical(_world_points(target, tu, tv))
        M = len(q)

        def nearest(c, k=1):
            d = ((c[:, None, :] - c_tgt[None, :, :]) ** 2).sum(-1)
            return np.argsort(d, axis=1)[:, :k]

        true_i = nearest(c_src + rng.normal(0, self.noise, c_src.shape))[:, 0]
        near_i = nearest(c_src + rng.normal(0, 0.15, c_src.shape))[:, 0]
        flip_i = nearest(c_src * np.array([1.0, -1.0, 1.0]) + rng.normal(0, self.noise, c_src.shape))[:, 0]
        rand_i = rng.integers(0, len(tu), (M, max(top_n, 5)))
        idx = np.column_stack([true_i, near_i, flip_i, rand_i[:, :2]])
        score = np.tile([0.9, 0.7, 0.6, 0.3, 0.25], (M, 1)) + rng.uniform(0, 0.05, (M, 5))
        outlier = rng.random(M) < self.outlier_rate
        flip = rng.random(M) < self.flip_fraction
        score[outlier & flip, 2] = 0.97
        score[outlier & ~flip, 3] = 0.97
        drop = outlier & (rng.random(M) >= self.true_in_pool)
        idx[drop, 0] = rand_i[drop, 2]
        score[drop, 0] = 0.2
        order = np.argsort(-score, axis=1)
        idx = np.take_along_axis(idx, order, 1)
        score = np.take_along_axis(score, order, 1)
        if top_n > 5:
            idx = np.column_stack([idx, rand_i[:, : top_n - 5]])
            score = np.column_stack([score, np.full((M, top_n - 5), 0.1)])
        idx, score = idx[:, :top_n], score[:, :top_n]
        cand = np.stack([tu[idx], tv[idx]], axis=-1)
        return MatchPool(q, cand, score)


def joint_angles(P: dict[str, np.ndarray], yaw_hint: float | None = None) -> np.ndarray:
    """A few human joint angles with a G1 counterpart (radians), from 3D keypoints."""

    def angle(a, b, c):  # flexion at b: 0 when straight
        u, v = a - b, c - b
        cosv = u @ v / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-9)
        return float(np.pi - np.arccos(np.clip(cosv, -1, 1)))

    up = P["neck"] - P["pelvis"]
    up = up / np.linalg.norm(up)
    out = []
    for side in ("left", "right"):
        thigh = P[f"{side}_knee"] - P[f"{side}_hip"]
        out.append(float(np.arccos(np.clip(-thigh @ up / np.linalg.norm(thigh), -1, 1))) * -1.0)
        out.append(angle(P[f"{side}_hip"], P[f"{side}_knee"], P[f"{side}_ankle"]))
    vertical = np.array([0.0, 0.0, 1.0]) if yaw_hint is not None else up
    out.append(float(np.arccos(np.clip(up @ vertical, -1, 1))))
    for side in ("left", "right"):
        arm = P[f"{side}_elbow"] - P[f"{side}_shoulder"]
        out.append(float(np.arccos(np.clip(-arm @ up / np.linalg.norm(arm), -1, 1))) * -1.0)
        out.append(angle(P[f"{side}_shoulder"], P[f"{side}_elbow"], P[f"{side}_wrist"]))
    return np.array(out)


class SyntheticPoseEstimator:
    name = "synthetic"

    def __init__(self, joint_noise_px: float = 3.0, joint_noise_m: float = 0.02, seed: int = 0):
        self.joint_noise_px, self.joint_noise_m, self.seed = float(joint_noise_px), float(joint_noise_m), int(seed)

    def estimate(self, image: PerceptionImage) -> HumanPose2D3D | None:
        gt = image.ground_truth
        if not isinstance(gt, DemoGroundTruth):
            raise PerceptionError(INVALID_REQUEST, "the synthetic pose estimator needs a synthetic demonstration image")
        if not gt.human_present or not (gt.labels == PERSON).any():
            return None
        rng = _rng(self.seed, image, 5)
        world = np.stack([gt.keypoints_world[k] for k in KEYPOINTS])
        cam = gt.camera_pose.inverse_apply(world)
        uv = gt.camera.project(cam) + rng.normal(0, self.joint_noise_px, (len(KEYPOINTS), 2))
        xyz = cam + rng.normal(0, self.joint_noise_m, cam.shape)
        vis = np.array([1.0 if gt.keypoints_visible[k] else 0.2 for k in KEYPOINTS])
        angles = joint_angles({k: world[i] for i, k in enumerate(KEYPOINTS)}, 0.0)
        return HumanPose2D3D(KEYPOINTS, uv, vis, xyz, LIMB_JOINTS, angles, 0.9)


register("detector", "synthetic")(lambda **p: SyntheticDetector(**p))
register("segmenter", "synthetic")(lambda **p: SyntheticSegmenter(**p))
register("depth_estimator", "synthetic")(lambda **p: SyntheticDepthEstimator(**p))
register("matcher", "synthetic")(lambda **p: SyntheticMatcher(**p))
register("pose_estimator", "synthetic")(lambda **p: SyntheticPoseEstimator(**p))
