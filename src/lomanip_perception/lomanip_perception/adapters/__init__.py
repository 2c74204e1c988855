"""Adapters for the paper's foundation models (and maintained alternatives), one module per model.

Registered lazily: importing this package imports no torch/transformers/diffusers; a backend's
module is imported only when a configuration selects it, and each adapter checks that its weights
are on disk (explicit folder or local Hugging Face cache) before importing any of them, so a
missing model fails in milliseconds with one line (ModelUnavailableError). Nothing is downloaded.

  role             backend              model (library)
  image_generator  flux                 FLUX.1 (diffusers FluxPipeline)
  detector         florence2            Florence-2 open-vocabulary detection (transformers)
  segmenter        sam2                 SAM 2 box prompts (transformers Sam2Model)
  depth_estimator  depth_anything_v2    Depth Anything V2 metric (transformers)
                   metric3d             Metric3D v2: no adapter in this build (see below)
  matcher          dinov2               DINOv2 dense features, top-N pool (transformers)
                   geoaware_sc          alias of dinov2 (GeoAware-SC's backbone only), says so
  pose_estimator   vitpose              ViTPose 2D + metric-depth lifting (transformers)
                   wham                 WHAM: no adapter in this build (see below)
"""
from __future__ import annotations

import importlib
import logging
from typing import Any, Callable, MutableMapping

from ..errors import ModelUnavailableError

log = logging.getLogger("lomanip_perception.adapters")

#: (role, backend) -> (module, class)
ADAPTERS: dict[tuple[str, str], tuple[str, str]] = {
    ("image_generator", "flux"): ("flux", "FluxGenerator"),
    ("detector", "florence2"): ("florence2", "Florence2Detector"),
    ("segmenter", "sam2"): ("sam2", "Sam2Segmenter"),
    ("depth_estimator", "depth_anything_v2"): ("depth_anything", "DepthAnythingV2Estimator"),
    ("matcher", "dinov2"): ("dinov2", "Dinov2Matcher"),
    ("pose_estimator", "vitpose"): ("vitpose", "ViTPoseEstimator"),
}

#: the paper's models this build cannot load, and what to use instead (one line each)
UNAVAILABLE = {
    ("depth_estimator", "metric3d"): (
        "Metric3D v2 (depth_estimator): no adapter in this build: Metric3D v2 ships as GitHub/torch.hub code "
        "(mmcv-style), not as a maintained library, so it cannot be loaded from local weights here; set "
        "models.depth_estimator.backend: depth_anything_v2 (Depth Anything V2 metric, transformers)"),
    ("pose_estimator", "wham"): (
        "WHAM (pose_estimator): no adapter in this build: WHAM has no packaged release and needs the "
        "licence-gated SMPL body model; set models.pose_estimator.backend: vitpose (ViTPose 2D keypoints lifted "
        "with the metric depth model, transformers)"),
}


def _lazy(module: str, cls: str) -> Callable[..., Any]:
    def factory(**params: Any) -> Any:
        mod = importlib.import_module(f"{__name__}.{module}")
        return getattr(mod, cls)(**params)

    factory.__doc__ = f"lomanip_perception.adapters.{module}.{cls} (imported on first use)"
    return factory


def _geoaware_sc(**params: Any) -> Any:
    log.warning("matcher 'geoaware_sc': serving with DINOv2 features only (GeoAware-SC's backbone); its Stable "
                "Diffusion features and trained post-processor are not part of this build")
    return _lazy("dinov2", "Dinov2Matcher")(**params)


def _unavailable(message: str) -> Callable[..., Any]:
    def factory(**params: Any) -> Any:
        raise ModelUnavailableError(message)

    return factory


def register_adapters(registry: MutableMapping[str, MutableMapping[str, Callable[..., Any]]]) -> None:
    """Add every adapter's lazy factory to ``registry[role][backend]``."""
    for (role, name), (module, cls) in ADAPTERS.items():
        registry[role][name] = _lazy(module, cls)
    registry["matcher"]["geoaware_sc"] = _geoaware_sc
    for (role, name), message in UNAVAILABLE.items():
        registry[role][name] = _unavailable(message)
