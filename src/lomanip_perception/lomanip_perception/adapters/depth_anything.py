"""Depth Anything V2 (metric head) as the ``depth_estimator`` role: the maintained transformers
alternative to Metric3D v2 (paper ref. [24]).

Preprocessing as the DPT image processor of the Depth Anything V2 checkpoints does, in numpy/cv2
(no torchvision): keep the aspect ratio, scale so both sides are at least ``input_size`` (518),
round each side to a multiple of the patch size (14), bicubic, ImageNet normalisation. The metric
head outputs metres directly (sigmoid x ``max_depth``: 20 m for the indoor checkpoints, 80 m for
the outdoor ones); the prediction is resized back to the image with bicubic interpolation.

Difference to Metric3D v2, which the paper uses: Metric3D takes the camera focal length and
rescales its canonical-camera depth with it; Depth Anything V2 metric does not take intrinsics, so
its metric scale is whatever its training cameras imply. The contact transfer solves a similarity
transform (scale included) by default, which absorbs a global scale error.
"""
from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from ..datatypes import PerceptionImage
from . import _common as c

DEFAULT_REPO = "depth-anything/Depth-Anything-V2-Metric-Indoor-Large-hf"


def dpt_size(h: int, w: int, target: int, multiple: int) -> tuple[int, int]:
    """Keep aspect, both sides >= target ('lower_bound'), each rounded to a multiple."""
    scale = max(target / h, target / w)

    def rnd(x: float) -> int:
        y = int(round(x / multiple) * multiple)
        return y if y >= x else int(np.ceil(x / multiple) * multiple)

    return rnd(h * scale), rnd(w * scale)


class DepthAnythingV2Estimator:
    name = "depth_anything_v2"

    def __init__(self, path: str = "", repo_id: str = DEFAULT_REPO, device: str = "auto", dtype: str = "auto",
                 input_size: int = 518, max_depth_clip: float = 0.0, role: str = "depth_estimator"):  # fmt: skip
        self.spec = c.WeightsSpec("Depth Anything V2 metric", role, path, repo_id)
        self.folder: Path = c.resolve_weights(self.spec)
        self.device, self.dtype = c.torch_setup(self.spec.model, role, device, dtype)
        t0 = time.perf_counter()
        from transformers import DepthAnythingForDepthEstimation

        c.quiet_hf()
        key = ("depth_anything_v2", str(self.folder), str(self.device), str(self.dtype))
        self.model = c.shared(key, lambda: c.load_or_fail(self.spec, self.folder, lambda: (
            DepthAnythingForDepthEstimation.from_pretrained(self.folder, local_files_only=True, dtype=self.dtype)
            .to(self.device).eval())))  # fmt: skip
        if getattr(self.model.config, "depth_estimation_type", "relative") != "metric":
            raise c.ModelUnavailableError(
                f"{self.spec.model} ({role}): the checkpoint in {self.folder} predicts RELATIVE depth "
                f"(depth_estimation_type != 'metric'); point {self.spec.parameter} at a metric checkpoint "
                f"such as {DEFAULT_REPO}")
        pre = c.read_json(self.folder, "preprocessor_config.json")
        self.input_size = int(input_size)
        self.multiple = int(pre.get("ensure_multiple_of") or self.model.config.backbone_config.patch_size)
        self.mean = tuple(pre.get("image_mean") or c.IMAGENET_MEAN)
        self.std = tuple(pre.get("image_std") or c.IMAGENET_STD)
        self.max_depth_clip = float(max_depth_clip)
        self._last: tuple[str, np.ndarray] | None = None
        self.load_seconds = time.perf_counter() - t0
        self.description = c.describe(self.spec.model, self.folder, self.device, self.dtype)

    def estimate(self, image: PerceptionImage) -> np.ndarray:
        """Metric depth (H, W) float32 in metres along the optical axis."""
        import torch
        import torch.nn.functional as F

        rgb = c.rgb_of(image, self.spec.model)
        digest = hashlib.blake2b(rgb.tobytes(), digest_size=16).hexdigest()
        if self._last is not None and self._last[0] == digest:  # the pose estimator asked for the same image
            return self._last[1].copy()
        H, W = rgb.shape[:2]
        h, w = dpt_size(H, W, self.input_size, self.multiple)
        pixels = torch.from_numpy(c.to_tensor(rgb, (h, w), self.mean, self.std, "bicubic")).to(self.device, self.dtype)
        with torch.inference_mode():
            pred = self.model(pixel_values=pixels).predicted_depth  # (1, h, w) metres
            depth = F.interpolate(pred[:, None].float(), (H, W), mode="bicubic", align_corners=False)[0, 0]
        out = depth.clamp_min(1e-3).cpu().numpy().astype(np.float32)
        if self.max_depth_clip > 0:
            out = np.minimum(out, self.max_depth_clip)
        self._last = (digest, out)
        return out.copy()
