"""What every model adapter shares: find weights offline, pick device/dtype, import torch late.

Why: a parameter file naming the paper's models must fail in well under a second with ONE line
("<model>: weights not found; set <parameter> ...; looked in ...") when the weights are absent, and
never touch the network. So weights are resolved with plain filesystem checks (an explicit folder,
or the local Hugging Face cache layout) BEFORE torch/transformers/diffusers are imported, and every
loader is called with ``local_files_only=True`` under ``HF_HUB_OFFLINE=1``.
"""
from __future__ import annotations

import logging
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..datatypes import PerceptionImage
from ..errors import INVALID_REQUEST, ModelUnavailableError, PerceptionError

log = logging.getLogger("lomanip_perception.adapters")

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def hf_cache_dir() -> Path:
    """The Hugging Face hub cache, as huggingface_hub resolves it (HF_HUB_CACHE > HF_HOME/hub)."""
    if os.environ.get("HF_HUB_CACHE"):
        return Path(os.environ["HF_HUB_CACHE"]).expanduser()
    home = os.environ.get("HF_HOME") or os.path.join(os.environ.get("XDG_CACHE_HOME", "~/.cache"), "huggingface")
    return Path(home).expanduser() / "hub"


def _cached_snapshot(repo_id: str, marker: str) -> tuple[Path | None, Path]:
    """The snapshot folder of ``repo_id`` in the local HF cache holding ``marker`` (refs/main first)."""
    repo_dir = hf_cache_dir() / ("models--" + repo_id.replace("/", "--"))
    snaps = repo_dir / "snapshots"
    ref = repo_dir / "refs" / "main"
    candidates = []
    if ref.is_file():
        candidates.append(snaps / ref.read_text().strip())
    if snaps.is_dir():
        candidates += sorted((p for p in snaps.iterdir() if p.is_dir()), key=lambda p: p.stat().st_mtime, reverse=True)
    for c in candidates:
        if (c / marker).is_file():
            return c, repo_dir
    return None, repo_dir


@dataclass(frozen=True)
class WeightsSpec:
    """Where one model's weights may be: ``path`` (explicit folder) or ``repo_id`` in the HF cache."""

    model: str  # human name, e.g. "Florence-2"
    role: str  # the perception role (for the parameter name in messages)
    path: str = ""
    repo_id: str = ""
    marker: str = "config.json"  # a file that must exist in a complete folder

    @property
    def parameter(self) -> str:
        return f"models.{self.role}.params.path"


def resolve_weights(spec: WeightsSpec) -> Path:
    """The local folder with the weights, or ModelUnavailableError with one actionable line."""
    looked = []
    if spec.path:
        p = Path(spec.path).expanduser()
        if (p / spec.marker).is_file():
            return p
        looked.append(f"{p} ({'no ' + spec.marker if p.is_dir() else 'no such folder'})")
    if spec.repo_id:
        snap, repo_dir = _cached_snapshot(spec.repo_id, spec.marker)
        if snap is not None:
            return snap
        looked.append(f"the Hugging Face cache {repo_dir} (HF_HUB_CACHE/HF_HOME)")
    hint = f" (e.g. a local copy of {spec.repo_id})" if spec.repo_id else ""
    raise ModelUnavailableError(
        f"{spec.model} ({spec.role}): weights not found; set {spec.parameter} to a folder holding {spec.marker}{hint} "
        f"or put {spec.repo_id or 'them'} in the local Hugging Face cache; looked in: {'; '.join(looked) or 'nowhere'}; "
        f"lomanip never downloads weights")


def offline_env() -> None:
    """Make every Hugging Face library refuse network access from here on (a user's explicit
    HF_HUB_OFFLINE=1 stays as it is; loaders also get local_files_only=True)."""
    os.environ["HF_HUB_OFFLINE"] = "1"
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
    os.environ.setdefault("HF_HUB_DISABLE_TELEMETRY", "1")


def torch_setup(model: str, role: str, device: str, dtype: str) -> tuple[Any, Any]:
    """(torch.device, torch.dtype) from parameters 'auto'|'cpu'|'cuda[:N]' and
    'auto'|'float32'|'float16'|'bfloat16'; a CUDA request without CUDA is a clear error."""
    offline_env()
    import torch

    dev = (device or "auto").strip().lower()
    if dev == "auto":
        dev = "cuda" if torch.cuda.is_available() else "cpu"
    if dev.startswith("cuda") and not torch.cuda.is_available():
        raise ModelUnavailableError(f"{model} ({role}): device {device!r} requested but this torch "
                                    f"({torch.__version__}) sees no CUDA device; set models.{role}.params.device: cpu")
    if not (dev == "cpu" or dev.startswith("cuda")):
        raise PerceptionError(INVALID_REQUEST, f"{model} ({role}): device must be auto, cpu or cuda[:N], got {device!r}")
    names = {"float32": torch.float32, "fp32": torch.float32, "float16": torch.float16, "fp16": torch.float16,
             "bfloat16": torch.bfloat16, "bf16": torch.bfloat16}
    dt = (dtype or "auto").strip().lower()
    if dt == "auto":
        tdt = torch.bfloat16 if dev.startswith("cuda") else torch.float32
    elif dt in names:
        tdt = names[dt]
    else:
        raise PerceptionError(INVALID_REQUEST, f"{model} ({role}): dtype must be auto, float32, float16 or "
                              f"bfloat16, got {dtype!r}")  # fmt: skip
    return torch.device(dev), tdt


def quiet_hf() -> None:
    """No progress bars or info chatter from the Hugging Face libraries in node logs."""
    try:
        from transformers.utils import logging as tlog

        tlog.set_verbosity_error()
        tlog.disable_progress_bar()
    except ImportError:
        pass
    try:
        from diffusers.utils import logging as dlog

        dlog.set_verbosity_error()
        dlog.disable_progress_bar()
    except ImportError:
        pass


def load_or_fail(spec: WeightsSpec, folder: Path, loader: Callable[[], Any]) -> Any:
    """Run a library loader; any failure becomes one line naming the model and the folder."""
    try:
        return loader()
    except ModelUnavailableError:
        raise
    except Exception as exc:  # a library's own error from deep inside: summarise it
        first = (str(exc).strip().splitlines() or [""])[0][:300]
        raise ModelUnavailableError(f"{spec.model} ({spec.role}): cannot load the weights in {folder} "
                                    f"({spec.parameter}): {type(exc).__name__}: {first}") from None


_SHARED: dict[tuple, Any] = {}
_SHARED_LOCK = threading.Lock()


def shared(key: tuple, build: Callable[[], Any]) -> Any:
    """One loaded model per key, so two roles using the same weights (the pose estimator lifting
    keypoints with the depth model) hold one copy in GPU memory."""
    with _SHARED_LOCK:
        if key not in _SHARED:
            _SHARED[key] = build()
        return _SHARED[key]


def rgb_of(image: PerceptionImage, who: str) -> np.ndarray:
    """The image's RGB as contiguous uint8 (H, W, 3), or INVALID_REQUEST."""
    rgb = image.rgb
    if rgb is None or rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] < 2 or rgb.shape[1] < 2:
        raise PerceptionError(INVALID_REQUEST, f"{who}: the image must be HxWx3 RGB, got shape "
                              f"{None if rgb is None else rgb.shape}")  # fmt: skip
    if rgb.dtype != np.uint8:
        scale = 255.0 if float(np.nanmax(rgb)) <= 1.0 else 1.0
        rgb = np.clip(np.nan_to_num(rgb.astype(np.float32)) * scale, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(rgb)


def to_tensor(rgb: np.ndarray, size_hw: tuple[int, int], mean=IMAGENET_MEAN, std=IMAGENET_STD,
              interpolation: str = "bicubic") -> np.ndarray:  # fmt: skip
    """Resize (cv2), scale to [0, 1], normalise: (1, 3, h, w) float32 numpy, the preprocessing the
    transformers image processors do, without torchvision (which does not import beside this torch)."""
    import cv2

    h, w = int(size_hw[0]), int(size_hw[1])
    interp = {"bicubic": cv2.INTER_CUBIC, "bilinear": cv2.INTER_LINEAR, "area": cv2.INTER_AREA}[interpolation]
    img = rgb if rgb.shape[:2] == (h, w) else cv2.resize(rgb, (w, h), interpolation=interp)
    x = img.astype(np.float32) / 255.0
    x = (x - np.asarray(mean, np.float32)) / np.asarray(std, np.float32)
    return np.ascontiguousarray(x.transpose(2, 0, 1)[None])


def read_json(folder: Path, name: str) -> dict:
    import json

    p = folder / name
    if not p.is_file():
        return {}
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return {}


def describe(model: str, folder: Path, device: Any, dtype: Any) -> str:
    return f"{model} from {folder} on {device} ({str(dtype).replace('torch.', '')})"
