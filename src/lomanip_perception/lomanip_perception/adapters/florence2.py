"""Florence-2 open-vocabulary detection (paper ref. [21]) as the ``detector`` role.

Why own pre/post-processing: Florence2Processor pulls image processors that need torchvision, which
does not import beside the CPU torch here; the model itself only needs normalised pixels and token
ids laid out as the processor would ("<image>" x N, <s>, task prompt, </s>). The generated text is
parsed here: Florence-2 answers ``<OPEN_VOCABULARY_DETECTION>`` / ``<OD>`` with
``label<loc_x0><loc_y0><loc_x1><loc_y1>...`` (coordinates quantised into 1000 bins of the image
width/height, polygons between ``<poly>`` markers), which becomes Detection boxes in pixels.

Scores: Florence-2 gives no per-box confidence. Every box of one answer gets the answer's
length-normalised sequence probability, and boxes of one answer are ordered largest first (in a
generated demonstration the object being handled is the prominent instance). Both are this
adapter's rules, not Florence-2's.
"""
from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from ..datatypes import Detection, PerceptionImage
from ..prompts import SYNONYMS
from . import _common as c

DEFAULT_REPO = "florence-community/Florence-2-large"
TASKS = {"open_vocabulary": "<OPEN_VOCABULARY_DETECTION>", "od": "<OD>"}
TASK_PROMPTS = {"<OPEN_VOCABULARY_DETECTION>": "Locate {label} in the image.",
                "<OD>": "Locate the objects with category name in the image."}
_SEGMENT = re.compile(r"([^<]*)((?:\s*<(?:loc_\d+|poly|/poly|sep)>)+)")
_LOC = re.compile(r"<loc_(\d+)>")


def parse_florence_output(text: str, width: int, height: int, bins: int = 1000,
                          default_label: str = "") -> list[tuple[str, tuple[float, float, float, float]]]:  # fmt: skip
    """(label, box in pixels) for every box or polygon in a Florence-2 detection answer.

    Boxes are groups of four ``<loc_k>`` (x0, y0, x1, y1); a polygon (``<poly>...</poly>``, the
    open-vocabulary task may answer with polygons) becomes its bounding box; an incomplete trailing
    group is dropped. A coordinate k maps to the centre of its bin, (k + 0.5) * size / bins, as
    Florence-2's own post-processor does."""
    for tok in ("</s>", "<s>", "<pad>"):
        text = text.replace(tok, "")
    out = []
    label = default_label
    for m in _SEGMENT.finditer(text):
        raw = m.group(1).strip(" .,;:\n\t")
        if raw:
            label = raw
        run = m.group(2)
        groups: list[list[int]] = []
        if "<poly>" in run:
            for poly in re.split(r"</?poly>|<sep>", run):
                locs = [int(k) for k in _LOC.findall(poly)]
                if len(locs) >= 4 and len(locs) % 2 == 0:
                    xs, ys = locs[0::2], locs[1::2]
                    groups.append([min(xs), min(ys), max(xs), max(ys)])
        else:
            locs = [int(k) for k in _LOC.findall(run)]
            groups = [locs[i:i + 4] for i in range(0, len(locs) - 3, 4)]
        for x0, y0, x1, y1 in groups:
            sx, sy = width / bins, height / bins
            box = ((min(x0, x1) + 0.5) * sx, (min(y0, y1) + 0.5) * sy, (max(x0, x1) + 0.5) * sx, (max(y0, y1) + 0.5) * sy)
            box = (float(np.clip(box[0], 0, width - 1)), float(np.clip(box[1], 0, height - 1)),
                   float(np.clip(box[2], 0, width - 1)), float(np.clip(box[3], 0, height - 1)))  # fmt: skip
            out.append((label, box))
    return out


def _canonical(label: str) -> str:
    words = label.lower().strip().split()
    noun = words[-1] if words else ""
    noun = SYNONYMS.get(noun, noun)
    return noun[:-1] if noun.endswith("s") and len(noun) > 3 else noun


def _tokens_for(size: int, kernels, strides, pads) -> int:
    for k, s, p in zip(kernels, strides, pads):
        size = (size + 2 * p - k) // s + 1
    return size


class Florence2Detector:
    """``detect(image, labels)``: one Florence-2 answer per label (open-vocabulary task) or one
    ``<OD>`` answer filtered to the labels; boxes best first."""

    name = "florence2"

    def __init__(self, path: str = "", repo_id: str = DEFAULT_REPO, device: str = "auto", dtype: str = "auto",
                 task: str = "open_vocabulary", num_beams: int = 3, max_new_tokens: int = 256,
                 min_box_px: float = 2.0):  # fmt: skip
        if task not in TASKS:
            raise ValueError(f"task must be one of {', '.join(TASKS)}, got {task!r}")
        self.spec = c.WeightsSpec("Florence-2", "detector", path, repo_id)
        self.folder: Path = c.resolve_weights(self.spec)  # before any heavy import: fail fast
        self.device, self.dtype = c.torch_setup("Florence-2", "detector", device, dtype)
        self.task, self.num_beams, self.max_new_tokens = TASKS[task], int(num_beams), int(max_new_tokens)
        self.min_box_px = float(min_box_px)
        t0 = time.perf_counter()
        from transformers import AutoTokenizer, Florence2ForConditionalGeneration

        c.quiet_hf()
        key = ("florence2", str(self.folder), str(self.device), str(self.dtype))  # one copy for all users
        self.tokenizer = c.shared(key + ("tokenizer",), lambda: c.load_or_fail(
            self.spec, self.folder, lambda: AutoTokenizer.from_pretrained(self.folder, local_files_only=True)))
        self.model = c.shared(key, lambda: c.load_or_fail(self.spec, self.folder, lambda: (
            Florence2ForConditionalGeneration.from_pretrained(self.folder, local_files_only=True, dtype=self.dtype)
            .to(self.device).eval())))
        pre = c.read_json(self.folder, "preprocessor_config.json")
        size = pre.get("size") or {}
        self.size_hw = (int(size.get("height", 768)), int(size.get("width", 768)))
        self.mean = tuple(pre.get("image_mean") or c.IMAGENET_MEAN)
        self.std = tuple(pre.get("image_std") or c.IMAGENET_STD)
        post = (c.read_json(self.folder, "processor_config.json").get("post_processor_config") or {})
        self.bins = int(post.get("quantize_bins", [1000])[0] if isinstance(post.get("quantize_bins"), list)
                        else post.get("quantize_bins", 1000))  # fmt: skip
        vc = self.model.config.vision_config
        n = [_tokens_for(s, vc.patch_size, vc.patch_stride, vc.patch_padding) for s in self.size_hw]
        self.num_image_tokens = n[0] * n[1] + 1  # the projector appends one temporal token
        self.load_seconds = time.perf_counter() - t0
        self.description = c.describe("Florence-2", self.folder, self.device, self.dtype)

    def _input_ids(self, prompt: str):
        import torch

        tok = self.tokenizer
        ids = tok(prompt, add_special_tokens=False)["input_ids"]
        seq = [self.model.config.image_token_id] * self.num_image_tokens + [tok.bos_token_id] + list(ids) + [tok.eos_token_id]
        return torch.tensor([seq], device=self.device)

    def answer(self, image: PerceptionImage, prompt: str) -> tuple[str, float]:
        """Florence-2's raw text answer to a task prompt, and its sequence probability."""
        import torch

        rgb = c.rgb_of(image, "Florence-2")
        pixels = torch.from_numpy(c.to_tensor(rgb, self.size_hw, self.mean, self.std)).to(self.device, self.dtype)
        with torch.inference_mode():
            out = self.model.generate(input_ids=self._input_ids(prompt), pixel_values=pixels,
                                      max_new_tokens=self.max_new_tokens, num_beams=self.num_beams, do_sample=False,
                                      output_scores=True, return_dict_in_generate=True)  # fmt: skip
            if getattr(out, "sequences_scores", None) is not None:
                score = float(torch.exp(out.sequences_scores[0]))
            else:
                ts = self.model.compute_transition_scores(out.sequences, out.scores, normalize_logits=True)
                score = float(torch.exp(ts[0].float().mean())) if ts.numel() else 0.0
        text = self.tokenizer.decode(out.sequences[0].tolist(), skip_special_tokens=False)
        return text, score

    def detect(self, image: PerceptionImage, labels: Sequence[str]) -> list[Detection]:
        H, W = image.height, image.width
        out: list[Detection] = []
        if self.task == "<OD>":
            text, score = self.answer(image, TASK_PROMPTS["<OD>"])
            wanted = {_canonical(lb): lb for lb in labels}
            found = [(wanted[_canonical(lb)], box) for lb, box in parse_florence_output(text, W, H, self.bins)
                     if _canonical(lb) in wanted]  # fmt: skip
            out = [Detection(lb, box, score) for lb, box in found]
        else:
            for label in labels:
                text, score = self.answer(image, TASK_PROMPTS["<OPEN_VOCABULARY_DETECTION>"].format(label=label))
                # the answer echoes the query; the requested class is the label the pipeline asked for
                out += [Detection(label, box, score) for _, box in parse_florence_output(text, W, H, self.bins, label)]
        out = [d for d in out if d.box[2] - d.box[0] >= self.min_box_px and d.box[3] - d.box[1] >= self.min_box_px]
        return sorted(out, key=lambda d: (-d.score, -(d.box[2] - d.box[0]) * (d.box[3] - d.box[1])))
