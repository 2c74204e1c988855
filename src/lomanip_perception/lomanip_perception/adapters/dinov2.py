"""Semantic correspondences from DINOv2 features (transformers) as the ``matcher`` role.

DINOv2 is the backbone of GeoAware-SC (paper ref. [25]); this adapter uses its dense patch
features alone. Not included from GeoAware-SC: the Stable Diffusion feature branch, the trained
geometry-aware post-processor and the test-time pose (flip) alignment; so left/right symmetric
confusions are more frequent than with GeoAware-SC, which the geometry-aware transfer's candidate
pool and overlap scoring are there to absorb (paper Sec. III-A2).

For each image the object is cropped to its mask's bounding box (plus ``crop_margin``) so the
feature grid is spent on the object, resized so the long side is ``input_size`` (each side a
multiple of the 14-pixel patch), normalised (ImageNet), and the last layer's patch tokens are
L2-normalised into a (C, h, w) grid. Query and candidate pixels read that grid bilinearly.
Candidates are the target mask's pixels on a ``stride_px`` grid; each query keeps its top-N by
cosine similarity, greedily suppressing candidates within ``nms_radius_px`` of a better one so the
pool holds N distinct places (the paper's pool). Scores are (1 + cosine) / 2, in [0, 1].
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..datatypes import MatchPool, PerceptionImage
from ..errors import CONTACT_TRANSFER_FAILED, INVALID_REQUEST, PerceptionError
from . import _common as c

DEFAULT_REPO = "facebook/dinov2-base"


class Dinov2Matcher:
    name = "dinov2"

    def __init__(self, path: str = "", repo_id: str = DEFAULT_REPO, device: str = "auto", dtype: str = "auto",
                 input_size: int = 448, crop_margin: float = 0.1, stride_px: int = 4, nms_radius_px: float = 8.0,
                 max_candidates: int = 20000):  # fmt: skip
        self.spec = c.WeightsSpec("DINOv2", "matcher", path, repo_id)
        self.folder: Path = c.resolve_weights(self.spec)
        self.device, self.dtype = c.torch_setup("DINOv2", "matcher", device, dtype)
        t0 = time.perf_counter()
        from transformers import AutoModel

        c.quiet_hf()
        self.model = c.load_or_fail(self.spec, self.folder, lambda: AutoModel.from_pretrained(
            self.folder, local_files_only=True, dtype=self.dtype).to(self.device).eval())
        cfg = self.model.config
        if cfg.model_type not in ("dinov2", "dinov2_with_registers"):
            raise c.ModelUnavailableError(f"DINOv2 (matcher): {self.folder} holds a {cfg.model_type!r} model, not "
                                          f"DINOv2; set {self.spec.parameter}")  # fmt: skip
        self.patch = int(cfg.patch_size)
        self.skip_tokens = 1 + int(getattr(cfg, "num_register_tokens", 0) or 0)
        pre = c.read_json(self.folder, "preprocessor_config.json")
        self.mean = tuple(pre.get("image_mean") or c.IMAGENET_MEAN)
        self.std = tuple(pre.get("image_std") or c.IMAGENET_STD)
        self.input_size, self.crop_margin = int(input_size), float(crop_margin)
        self.stride_px, self.nms_radius_px, self.max_candidates = int(stride_px), float(nms_radius_px), int(max_candidates)
        self.load_seconds = time.perf_counter() - t0
        self.description = c.describe("DINOv2", self.folder, self.device, self.dtype)

    def _feature_grid(self, rgb: np.ndarray, mask: np.ndarray):
        """(grid (1, C, h, w) torch, crop box (x0, y0, x1, y1) in pixels)."""
        import torch

        v, u = np.nonzero(mask)
        H, W = mask.shape
        mx = self.crop_margin * max(u.max() - u.min() + 1, v.max() - v.min() + 1)
        x0, x1 = int(max(0, np.floor(u.min() - mx))), int(min(W, np.ceil(u.max() + 1 + mx)))
        y0, y1 = int(max(0, np.floor(v.min() - mx))), int(min(H, np.ceil(v.max() + 1 + mx)))
        crop = rgb[y0:y1, x0:x1]
        s = self.input_size / max(crop.shape[:2])
        h = max(self.patch, int(round(crop.shape[0] * s / self.patch)) * self.patch)
        w = max(self.patch, int(round(crop.shape[1] * s / self.patch)) * self.patch)
        pixels = torch.from_numpy(c.to_tensor(crop, (h, w), self.mean, self.std, "bicubic")).to(self.device, self.dtype)
        with torch.inference_mode():
            tokens = self.model(pixel_values=pixels).last_hidden_state[:, self.skip_tokens:].float()
        grid = tokens.reshape(1, h // self.patch, w // self.patch, -1).permute(0, 3, 1, 2)
        grid = torch.nn.functional.normalize(grid, dim=1)
        return grid, (x0, y0, x1, y1)

    @staticmethod
    def _sample(grid, box, uv: np.ndarray):
        """(M, C) unit features at pixel centres uv (M, 2) inside the crop box."""
        import torch
        import torch.nn.functional as F

        x0, y0, x1, y1 = box
        gx = (uv[:, 0] + 0.5 - x0) / (x1 - x0) * 2.0 - 1.0
        gy = (uv[:, 1] + 0.5 - y0) / (y1 - y0) * 2.0 - 1.0
        g = torch.from_numpy(np.stack([gx, gy], -1).astype(np.float32)).to(grid.device)[None, None]
        f = F.grid_sample(grid, g, mode="bilinear", padding_mode="border", align_corners=False)[0, :, 0].T
        return F.normalize(f, dim=1)

    def match(self, source: PerceptionImage, source_mask: np.ndarray, query_uv: np.ndarray,
              target: PerceptionImage, target_mask: np.ndarray, top_n: int) -> MatchPool:  # fmt: skip
        import torch

        q = np.asarray(query_uv, int).reshape(-1, 2)
        src_rgb, tgt_rgb = c.rgb_of(source, "DINOv2"), c.rgb_of(target, "DINOv2")
        for what, img, m in (("source", src_rgb, source_mask), ("target", tgt_rgb, target_mask)):
            if m is None or m.shape != img.shape[:2]:
                raise PerceptionError(INVALID_REQUEST, f"DINOv2 matcher: the {what} mask must match its image size")
            if not m.any():
                raise PerceptionError(CONTACT_TRANSFER_FAILED, f"DINOv2 matcher: the {what} mask is empty")
        if top_n < 1 or len(q) == 0:
            raise PerceptionError(INVALID_REQUEST, "DINOv2 matcher: need top_n >= 1 and at least one query point")
        sgrid, sbox = self._feature_grid(src_rgb, source_mask)
        tgrid, tbox = self._feature_grid(tgt_rgb, target_mask)
        grid_mask = np.zeros_like(target_mask)
        grid_mask[self.stride_px // 2::self.stride_px, self.stride_px // 2::self.stride_px] = True
        tv, tu = np.nonzero(target_mask & grid_mask)
        if len(tu) < top_n:
            tv, tu = np.nonzero(target_mask)
        if len(tu) > self.max_candidates:
            keep = np.linspace(0, len(tu) - 1, self.max_candidates).astype(int)
            tu, tv = tu[keep], tv[keep]
        cand = np.stack([tu, tv], -1)
        with torch.inference_mode():
            fq = self._sample(sgrid, sbox, q.astype(float))
            ft = self._sample(tgrid, tbox, cand.astype(float))
            sim = (fq @ ft.T).cpu().numpy()  # (M, T) cosine
        k = min(sim.shape[1], max(top_n * 30, 64))
        pre = np.argpartition(-sim, k - 1, axis=1)[:, :k] if k < sim.shape[1] else np.tile(np.arange(sim.shape[1]), (len(q), 1))
        out_idx = np.zeros((len(q), top_n), int)
        out_sc = np.zeros((len(q), top_n))
        r2 = self.nms_radius_px ** 2
        for i in range(len(q)):
            order = pre[i][np.argsort(-sim[i, pre[i]])]
            chosen: list[int] = []
            for j in order:
                if all(((cand[j] - cand[p]) ** 2).sum() >= r2 for p in chosen):
                    chosen.append(j)
                    if len(chosen) == top_n:
                        break
            for j in order:  # fewer distinct places than top_n: fill with the next best
                if len(chosen) == top_n:
                    break
                if j not in chosen:
                    chosen.append(j)
            while len(chosen) < top_n:
                chosen.append(chosen[-1])
            out_idx[i] = chosen
            out_sc[i] = (1.0 + sim[i, chosen]) / 2.0
        return MatchPool(q, cand[out_idx], out_sc)
