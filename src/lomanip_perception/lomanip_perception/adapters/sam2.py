"""SAM 2 (paper ref. [22]) refining detector boxes into masks, as the ``segmenter`` role.

transformers' Sam2Model takes normalised square pixels and boxes in that square's coordinates;
Sam2Processor is not used because its image processor imports torchvision (which does not import
beside this CPU torch). The steps it would do are here: resize to the model's square input
(SAM 2 does not keep the aspect ratio), ImageNet normalisation, boxes scaled per axis, and the
low-resolution mask logits upsampled to the input square, then to the image, thresholded at 0.

With ``multimask_output`` the mask with the best predicted IoU is kept (SAM 2's own choice for an
ambiguous prompt); ``clip_to_box`` (this adapter's rule, default on) drops mask pixels more than
``box_margin_px`` outside the prompt box, so a leak onto a touching object does not reach the
contact transfer.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Sequence

import numpy as np

from ..datatypes import Detection, PerceptionImage
from . import _common as c

DEFAULT_REPO = "facebook/sam2.1-hiera-large"


class Sam2Segmenter:
    name = "sam2"

    def __init__(self, path: str = "", repo_id: str = DEFAULT_REPO, device: str = "auto", dtype: str = "auto",
                 multimask_output: bool = True, clip_to_box: bool = True, box_margin_px: float = 4.0,
                 mask_threshold: float = 0.0):  # fmt: skip
        self.spec = c.WeightsSpec("SAM 2", "segmenter", path, repo_id)
        self.folder: Path = c.resolve_weights(self.spec)
        self.device, self.dtype = c.torch_setup("SAM 2", "segmenter", device, dtype)
        self.multimask, self.clip_to_box = bool(multimask_output), bool(clip_to_box)
        self.box_margin_px, self.mask_threshold = float(box_margin_px), float(mask_threshold)
        t0 = time.perf_counter()
        from transformers import Sam2Model

        c.quiet_hf()
        self.model = c.load_or_fail(self.spec, self.folder, lambda: Sam2Model.from_pretrained(
            self.folder, local_files_only=True, dtype=self.dtype).to(self.device).eval())
        size = int(self.model.config.prompt_encoder_config.image_size)
        self.size = size
        pre = c.read_json(self.folder, "preprocessor_config.json")
        self.mean = tuple(pre.get("image_mean") or c.IMAGENET_MEAN)
        self.std = tuple(pre.get("image_std") or c.IMAGENET_STD)
        self.load_seconds = time.perf_counter() - t0
        self.description = c.describe("SAM 2", self.folder, self.device, self.dtype)

    def segment(self, image: PerceptionImage, detections: Sequence[Detection]) -> list[np.ndarray]:
        import torch
        import torch.nn.functional as F

        if not detections:
            return []
        rgb = c.rgb_of(image, "SAM 2")
        H, W = rgb.shape[:2]
        S = self.size
        pixels = torch.from_numpy(c.to_tensor(rgb, (S, S), self.mean, self.std, "bilinear")).to(self.device, self.dtype)
        boxes = np.array([d.box for d in detections], np.float32) * np.array([S / W, S / H, S / W, S / H], np.float32)
        with torch.inference_mode():
            out = self.model(pixel_values=pixels, input_boxes=torch.from_numpy(boxes)[None].to(self.device, self.dtype),
                             multimask_output=self.multimask)  # fmt: skip
            logits = out.pred_masks[0].float()  # (N, M, h, w)
            iou = out.iou_scores[0].float()  # (N, M)
            best = iou.argmax(dim=1)
            logits = logits[torch.arange(len(detections)), best][:, None]  # (N, 1, h, w)
            logits = F.interpolate(logits, (S, S), mode="bilinear", align_corners=False)
            logits = F.interpolate(logits, (H, W), mode="bilinear", align_corners=False)
        masks = (logits[:, 0] > self.mask_threshold).cpu().numpy()
        out_masks = []
        for det, m in zip(detections, masks):
            if self.clip_to_box:
                x0, y0, x1, y1 = det.box
                r = self.box_margin_px
                keep = np.zeros_like(m)
                keep[max(0, int(np.floor(y0 - r))):int(np.ceil(y1 + r)) + 1,
                     max(0, int(np.floor(x0 - r))):int(np.ceil(x1 + r)) + 1] = True  # fmt: skip
                m = m & keep
            out_masks.append(m.astype(bool))
        return out_masks
