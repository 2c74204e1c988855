"""ViTPose 2D keypoints lifted to 3D with the metric depth model, as the ``pose_estimator`` role.

Why not WHAM (paper ref. [26]): WHAM has no packaged release (research code on GitHub, built on the
SMPL body model, whose files are licence-gated and cannot be installed from a registry), so no
adapter can load it from a local folder through a maintained library. The alternative here is
ViTPose (transformers ``VitPoseForPoseEstimation``, Apache-2.0 checkpoints such as
usyd-community/vitpose-base-simple), chosen over MediaPipe BlazePose because it loads with the same
library and weight layout as the other adapters and can be tested with a tiny random-weight model.

What it gives and how (all in the R_g camera frame, the paper's heuristic intrinsics f = image
size, principal point = image centre, the same ones the pipeline lifts keypoints with):
 * 2D: top-down ViTPose on a person box (from a detector backend, e.g. Florence-2 "person", or the
   whole image), the box padded 1.25x to the model's aspect ratio and warped to its input size,
   heatmap argmax with the usual quarter-pixel shift toward the larger neighbour, mapped back.
 * 3D: each keypoint's depth is the median metric depth in a 5x5 window at its pixel plus the
   body's surface-to-joint offset, back-projected. Not a learned 3D body model: occluded joints
   take the depth of whatever hides them (their visibility is low, and the pipeline then rescales
   instead of trusting the pixel).
 * names: COCO-17 joints mapped to lomanip's keypoints; pelvis, neck and spine are midpoints; the
   palm centre is the wrist moved a third of the forearm further; with COCO-17 the sole centre,
   heel and toe are the ankle (no foot points), with COCO-WholeBody (133 keypoints) they come from
   the heel and toe points and the palm from the hand points.
 * joint angles: the same definitions as the synthetic stand-in (hip/shoulder pitch, knee/elbow
   flexion), with the waist pitch measured against the image's vertical (a level camera assumed).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..datatypes import HumanPose2D3D, PerceptionImage, PinholeCamera
from ..errors import INVALID_REQUEST, PerceptionError
from ..transfer import SURFACE_OFFSET
from . import _common as c

DEFAULT_REPO = "usyd-community/vitpose-base-simple"
COCO17 = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
          "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee",
          "right_knee", "left_ankle", "right_ankle")  # fmt: skip
#: COCO-WholeBody foot points (indices 17-22) and hand roots (91 left, 112 right)
WB_FEET = {"left_big_toe": 17, "left_small_toe": 18, "left_heel": 19, "right_big_toe": 20, "right_small_toe": 21,
           "right_heel": 22}  # fmt: skip
WB_HAND_ROOT = {"left": 91, "right": 112}
KEYPOINTS = ("pelvis", "spine", "neck", "head",
             "left_shoulder", "left_elbow", "left_wrist", "left_hand",
             "right_shoulder", "right_elbow", "right_wrist", "right_hand",
             "left_hip", "left_knee", "left_ankle", "left_heel", "left_toe", "left_foot",
             "right_hip", "right_knee", "right_ankle", "right_heel", "right_toe", "right_foot")  # fmt: skip


def refine_argmax(heatmaps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 2) heatmap coordinates (x, y) and (K,) peak values; argmax + quarter-pixel shift."""
    K, h, w = heatmaps.shape
    flat = heatmaps.reshape(K, -1)
    idx = flat.argmax(1)
    score = flat.max(1)
    x, y = (idx % w).astype(float), (idx // w).astype(float)
    for k in range(K):
        xi, yi = int(x[k]), int(y[k])
        if 0 < xi < w - 1:
            x[k] += 0.25 * np.sign(heatmaps[k, yi, xi + 1] - heatmaps[k, yi, xi - 1])
        if 0 < yi < h - 1:
            y[k] += 0.25 * np.sign(heatmaps[k, yi + 1, xi] - heatmaps[k, yi - 1, xi])
    return np.stack([x, y], -1), score


def crop_affine(box: tuple[float, float, float, float], out_hw: tuple[int, int], padding: float = 1.25) -> np.ndarray:
    """2x3 affine from image pixels to the model input for a box padded to the input aspect."""
    x0, y0, x1, y1 = box
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    bw, bh = max(x1 - x0, 1.0), max(y1 - y0, 1.0)
    oh, ow = out_hw
    aspect = ow / oh
    if bw > aspect * bh:
        bh = bw / aspect
    else:
        bw = bh * aspect
    bw, bh = bw * padding, bh * padding
    s = ow / bw
    return np.array([[s, 0.0, ow / 2.0 - s * cx], [0.0, s, oh / 2.0 - s * cy]])


def flexion(a: np.ndarray, b: np.ndarray, cpt: np.ndarray) -> float:
    u, v = a - b, cpt - b
    cosv = u @ v / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-9)
    return float(np.pi - np.arccos(np.clip(cosv, -1, 1)))


#: G1 joints the angles stand for (names as in the model), as the synthetic stand-in reports them
JOINT_NAMES = ("left_hip_pitch_joint", "left_knee_joint", "right_hip_pitch_joint", "right_knee_joint",
               "waist_pitch_joint", "left_shoulder_pitch_joint", "left_elbow_joint", "right_shoulder_pitch_joint",
               "right_elbow_joint")  # fmt: skip


def joint_angles(P: Mapping[str, np.ndarray], camera_up: np.ndarray = np.array([0.0, -1.0, 0.0])) -> np.ndarray:
    """Hip/shoulder pitch (minus the angle of thigh/upper arm from the torso's downward axis),
    knee/elbow flexion, waist pitch = torso lean from ``camera_up``; radians, order JOINT_NAMES."""
    up = P["neck"] - P["pelvis"]
    up = up / max(np.linalg.norm(up), 1e-9)
    out = []
    for side in ("left", "right"):
        thigh = P[f"{side}_knee"] - P[f"{side}_hip"]
        out.append(-float(np.arccos(np.clip(-thigh @ up / max(np.linalg.norm(thigh), 1e-9), -1, 1))))
        out.append(flexion(P[f"{side}_hip"], P[f"{side}_knee"], P[f"{side}_ankle"]))
    out.append(float(np.arccos(np.clip(up @ camera_up, -1, 1))))
    for side in ("left", "right"):
        arm = P[f"{side}_elbow"] - P[f"{side}_shoulder"]
        out.append(-float(np.arccos(np.clip(-arm @ up / max(np.linalg.norm(arm), 1e-9), -1, 1))))
        out.append(flexion(P[f"{side}_shoulder"], P[f"{side}_elbow"], P[f"{side}_wrist"]))
    return np.array(out)


def to_lomanip(named: dict[str, np.ndarray], score: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(24, 2) uv and (24,) visibility in KEYPOINTS order from model keypoints by name."""
    P, S = dict(named), dict(score)

    def mid(a, b, name):
        P[name] = (P[a] + P[b]) / 2.0
        S[name] = min(S[a], S[b])

    mid("left_hip", "right_hip", "pelvis")
    mid("left_shoulder", "right_shoulder", "neck")
    mid("pelvis", "neck", "spine")
    P["head"], S["head"] = P["nose"], S["nose"]
    for side in ("left", "right"):
        if f"{side}_palm" in P:
            P[f"{side}_hand"], S[f"{side}_hand"] = P[f"{side}_palm"], S[f"{side}_palm"]
        else:
            P[f"{side}_hand"] = P[f"{side}_wrist"] + (P[f"{side}_wrist"] - P[f"{side}_elbow"]) / 3.0
            S[f"{side}_hand"] = min(S[f"{side}_wrist"], S[f"{side}_elbow"])
        if f"{side}_heel" in P:
            toe = (P[f"{side}_big_toe"] + P[f"{side}_small_toe"]) / 2.0
            P[f"{side}_toe"], S[f"{side}_toe"] = toe, min(S[f"{side}_big_toe"], S[f"{side}_small_toe"])
            P[f"{side}_foot"] = (P[f"{side}_heel"] + toe) / 2.0
            S[f"{side}_foot"] = min(S[f"{side}_heel"], S[f"{side}_toe"])
        else:
            for part in ("heel", "toe", "foot"):
                P[f"{side}_{part}"], S[f"{side}_{part}"] = P[f"{side}_ankle"], S[f"{side}_ankle"]
    return np.stack([P[k] for k in KEYPOINTS]), np.array([S[k] for k in KEYPOINTS])


class ViTPoseEstimator:
    name = "vitpose"

    def __init__(self, path: str = "", repo_id: str = DEFAULT_REPO, device: str = "auto", dtype: str = "auto",
                 depth: Mapping[str, Any] | None = None, person_detector: Mapping[str, Any] | None = None,
                 dataset_index: int = 0, min_confidence: float = 0.3, padding: float = 1.25):  # fmt: skip
        self.spec = c.WeightsSpec("ViTPose", "pose_estimator", path, repo_id)
        self.folder: Path = c.resolve_weights(self.spec)
        if not depth or not depth.get("backend"):
            raise PerceptionError(INVALID_REQUEST, "vitpose (pose_estimator): set params.depth to a metric depth "
                                  "backend, e.g. {backend: depth_anything_v2, params: {path: ...}}: the 3D keypoints "
                                  "are lifted with it")  # fmt: skip
        from ..registry import build  # late: the registry imports this package lazily

        self.depth = build("depth_estimator", depth["backend"], depth.get("params") or {})
        self.detector = (build("detector", person_detector["backend"], person_detector.get("params") or {})
                         if person_detector and person_detector.get("backend") else None)  # fmt: skip
        self.device, self.dtype = c.torch_setup("ViTPose", "pose_estimator", device, dtype)
        t0 = time.perf_counter()
        from transformers import VitPoseForPoseEstimation

        c.quiet_hf()
        self.model = c.load_or_fail(self.spec, self.folder, lambda: VitPoseForPoseEstimation.from_pretrained(
            self.folder, local_files_only=True, dtype=self.dtype).to(self.device).eval())
        bb = self.model.config.backbone_config
        self.input_hw = tuple(int(s) for s in bb.image_size)
        self.num_experts = int(getattr(bb, "num_experts", 1))
        self.dataset_index, self.min_confidence, self.padding = int(dataset_index), float(min_confidence), float(padding)
        pre = c.read_json(self.folder, "preprocessor_config.json")
        self.mean = tuple(pre.get("image_mean") or c.IMAGENET_MEAN)
        self.std = tuple(pre.get("image_std") or c.IMAGENET_STD)
        self.load_seconds = time.perf_counter() - t0
        self.description = (c.describe("ViTPose", self.folder, self.device, self.dtype)
                            + f", 3D from {getattr(self.depth, 'name', '?')} depth"
                            + (f", person boxes from {self.detector.name}" if self.detector else ", whole-image box"))

    def keypoints_2d(self, rgb: np.ndarray, box) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """Model keypoints by name in image pixels, and their heatmap peak scores."""
        import cv2
        import torch

        A = crop_affine(box, self.input_hw, self.padding)
        oh, ow = self.input_hw
        crop = cv2.warpAffine(rgb, A, (ow, oh), flags=cv2.INTER_LINEAR)
        pixels = torch.from_numpy(c.to_tensor(crop, (oh, ow), self.mean, self.std)).to(self.device, self.dtype)
        kwargs = {"dataset_index": torch.tensor([self.dataset_index], device=self.device)} if self.num_experts > 1 else {}
        with torch.inference_mode():
            heat = self.model(pixel_values=pixels, **kwargs).heatmaps[0].float().cpu().numpy()
        xy, score = refine_argmax(heat)
        K, hh, hw = heat.shape
        inp = np.stack([(xy[:, 0] + 0.5) * ow / hw - 0.5, (xy[:, 1] + 0.5) * oh / hh - 0.5], -1)
        Ainv = cv2.invertAffineTransform(A)
        uv = inp @ Ainv[:, :2].T + Ainv[:, 2]
        if K >= 133:
            names = list(COCO17) + [None] * (K - 17)
            for n, i in WB_FEET.items():
                names[i] = n
            named = {n: uv[i] for i, n in enumerate(names) if n}
            sc = {n: float(score[i]) for i, n in enumerate(names) if n}
            for side, r in WB_HAND_ROOT.items():  # palm centre: wrist root and the four finger bases
                idx = [r, r + 5, r + 9, r + 13, r + 17]
                named[f"{side}_palm"] = uv[idx].mean(0)
                sc[f"{side}_palm"] = float(score[idx].min())
        elif K == 17:
            named = {n: uv[i] for i, n in enumerate(COCO17)}
            sc = {n: float(score[i]) for i, n in enumerate(COCO17)}
        else:
            raise PerceptionError(INVALID_REQUEST, f"ViTPose (pose_estimator): {K} keypoints in {self.folder}; "
                                  "supported layouts are COCO-17 and COCO-WholeBody-133")  # fmt: skip
        return named, sc

    def estimate(self, image: PerceptionImage) -> HumanPose2D3D | None:
        rgb = c.rgb_of(image, "ViTPose")
        H, W = rgb.shape[:2]
        if self.detector is not None:
            people = self.detector.detect(image, ["person"])
            if not people:
                return None
            box = people[0].box
        else:
            box = (0.0, 0.0, W - 1.0, H - 1.0)
        named, score = self.keypoints_2d(rgb, box)
        uv, conf = to_lomanip(named, score)
        vis = np.clip(conf, 0.0, 1.0)
        confidence = float(np.clip(np.mean(conf[[KEYPOINTS.index(k) for k in ("left_hip", "right_hip", "left_shoulder",
                                                                                 "right_shoulder")]]), 0, 1))  # fmt: skip
        if confidence < self.min_confidence:
            return None
        depth = np.asarray(self.depth.estimate(image), float)
        cam = PinholeCamera.paper_heuristic(W, H)
        z = np.empty(len(KEYPOINTS))
        for i, (name, (u, v)) in enumerate(zip(KEYPOINTS, uv)):
            ui, vi = int(np.clip(round(u), 0, W - 1)), int(np.clip(round(v), 0, H - 1))
            win = depth[max(0, vi - 2):vi + 3, max(0, ui - 2):ui + 3]
            win = win[np.isfinite(win) & (win > 0)]
            z[i] = (float(np.median(win)) if win.size else float(np.nanmedian(depth))) + SURFACE_OFFSET.get(
                name.split("_", 1)[-1], 0.04)
        xyz = cam.backproject(uv[:, 0], uv[:, 1], z)
        angles = joint_angles(dict(zip(KEYPOINTS, xyz)))
        return HumanPose2D3D(KEYPOINTS, uv, vis, xyz, JOINT_NAMES, angles, confidence)
