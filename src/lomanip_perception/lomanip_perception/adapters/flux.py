"""FLUX.1 text-to-image (paper ref. [20]) through diffusers' FluxPipeline, as ``image_generator``.

The prompt is the one the pipeline hands over: the paper's template built by
lomanip_perception.prompts.generation_prompt ("A scene of a person picking up the box. The person
has dark hair ..."). Several images are drawn per subtask, image k from its own CPU generator
seeded ``request.seed * 1000 + k`` (reproducible on any device, independent of how many are drawn),
and one is kept by the selection rule:

 * ``first``: image 0 (no extra model);
 * ``detector``: run a detector backend (e.g. Florence-2) for "person" and the subtask's object
   classes on every image; keep the image that shows the person and the most of the classes, ties
   broken by the weakest of those detections' scores, then by draw order. This is this adapter's
   rule; the paper does not state how it picks among generated images.

Resolution and steps are parameters (the request's 1024x1024 unless ``width``/``height`` are set;
FLUX needs multiples of 16). ``guidance_scale`` 3.5 and 28 steps are FLUX.1-dev's documented
defaults; FLUX.1-schnell wants guidance 0 and about 4 steps.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..datatypes import GenerationRequest, PerceptionImage
from ..errors import INVALID_REQUEST, PerceptionError
from . import _common as c

DEFAULT_REPO = "black-forest-labs/FLUX.1-dev"
SELECTIONS = ("first", "detector")


class FluxGenerator:
    name = "flux"

    def __init__(self, path: str = "", repo_id: str = DEFAULT_REPO, device: str = "auto", dtype: str = "auto",
                 num_inference_steps: int = 28, guidance_scale: float = 3.5, num_images: int = 4,
                 width: int = 0, height: int = 0, max_sequence_length: int = 512, selection: str = "first",
                 detector: Mapping[str, Any] | Any | None = None, cpu_offload: bool = False):  # fmt: skip
        if selection not in SELECTIONS:
            raise ValueError(f"selection must be one of {', '.join(SELECTIONS)}, got {selection!r}")
        if int(num_images) < 1 or int(num_inference_steps) < 1:
            raise ValueError("num_images and num_inference_steps must be >= 1")
        self.spec = c.WeightsSpec("FLUX.1", "image_generator", path, repo_id, marker="model_index.json")
        self.folder: Path = c.resolve_weights(self.spec)
        self.detector = None
        if selection == "detector":
            if detector is None:
                raise PerceptionError(INVALID_REQUEST, "flux: selection 'detector' needs params.detector, e.g. "
                                      "{backend: florence2, params: {path: ...}}")  # fmt: skip
            if isinstance(detector, Mapping):
                from ..registry import build

                self.detector = build("detector", detector["backend"], detector.get("params") or {})
            else:  # an already built detector object
                self.detector = detector
        self.device, self.dtype = c.torch_setup("FLUX.1", "image_generator", device, dtype)
        self.steps, self.guidance = int(num_inference_steps), float(guidance_scale)
        self.num_images, self.selection = int(num_images), selection
        self.width, self.height, self.max_sequence_length = int(width), int(height), int(max_sequence_length)
        t0 = time.perf_counter()
        from diffusers import FluxPipeline

        c.quiet_hf()

        def load():
            pipe = FluxPipeline.from_pretrained(self.folder, local_files_only=True, dtype=self.dtype)
            if cpu_offload and self.device.type == "cuda":
                pipe.enable_model_cpu_offload(device=self.device)  # fits a 24 GB card, slower
            else:
                pipe = pipe.to(self.device)
            pipe.set_progress_bar_config(disable=True)
            return pipe

        self.pipe = c.load_or_fail(self.spec, self.folder, load)
        self.multiple = 2 * int(getattr(self.pipe, "vae_scale_factor", 8))
        self.load_seconds = time.perf_counter() - t0
        self.description = (c.describe("FLUX.1", self.folder, self.device, self.dtype)
                            + f", {self.num_images} images x {self.steps} steps, selection '{self.selection}'")
        self.last_candidates: list[np.ndarray] = []
        self.last_selected: int = -1

    def _size(self, request: GenerationRequest) -> tuple[int, int]:
        w, h = self.width or int(request.width), self.height or int(request.height)
        if w <= 0 or h <= 0 or w % self.multiple or h % self.multiple:
            raise PerceptionError(INVALID_REQUEST, f"flux: width and height must be positive multiples of "
                                  f"{self.multiple}, got {w}x{h}")  # fmt: skip
        return w, h

    def images(self, request: GenerationRequest) -> list[np.ndarray]:
        """All ``num_images`` candidates as uint8 (H, W, 3), in draw order."""
        import torch

        if not request.prompt or not request.prompt.strip():
            raise PerceptionError(INVALID_REQUEST, "flux: empty prompt")
        w, h = self._size(request)
        gens = [torch.Generator("cpu").manual_seed(int(request.seed) * 1000 + k) for k in range(self.num_images)]
        with torch.inference_mode():
            out = self.pipe(prompt=request.prompt, height=h, width=w, num_inference_steps=self.steps,
                            guidance_scale=self.guidance, num_images_per_prompt=self.num_images, generator=gens,
                            max_sequence_length=self.max_sequence_length, output_type="np")  # fmt: skip
        arr = np.asarray(out.images)  # (N, H, W, 3) float in [0, 1]
        return [np.clip(np.round(a * 255.0), 0, 255).astype(np.uint8) for a in arr]

    def _select(self, candidates: list[np.ndarray], request: GenerationRequest) -> int:
        if self.selection == "first" or self.detector is None:
            return 0
        classes = list(getattr(request.subtask, "object_classes", []) or [])
        best, best_key = 0, None
        for k, rgb in enumerate(candidates):
            dets = self.detector.detect(PerceptionImage(rgb, source="flux candidate"), ["person"] + classes)
            found = {}
            for d in dets:
                found[d.label] = max(found.get(d.label, 0.0), d.score)
            has_person = "person" in found
            n = sum(1 for cl in classes if cl in found)
            weakest = min(found.values()) if found else 0.0
            key = (has_person, n, weakest)
            if best_key is None or key > best_key:
                best, best_key = k, key
        return best

    def generate(self, request: GenerationRequest) -> PerceptionImage:
        candidates = self.images(request)
        k = self._select(candidates, request)
        self.last_candidates, self.last_selected = candidates, k
        return PerceptionImage(candidates[k], source=f"flux (image {k} of {len(candidates)}, seed "
                                                     f"{int(request.seed) * 1000 + k})")  # fmt: skip
