"""The six model roles of the perception stage as small typed interfaces (paper Sec. III-A1/2).

Each role is a Protocol so a backend is any object with the right method; the registry
(registry.py) builds them by name from YAML/parameters. The paper's models and the roles they fill:

  image_generator   Flux (text-to-image LDM)                generate(request) -> PerceptionImage
  detector          Florence-2 (open-vocabulary boxes)       detect(image, labels) -> [Detection]
  segmenter         SAM 2 (box-prompted masks)               segment(image, detections) -> [mask]
  depth_estimator   Metric3D v2 (zero-shot metric depth)     estimate(image) -> depth (H, W) metres
  matcher           GeoAware-SC (semantic correspondences)   match(...) -> MatchPool (top-N per point)
  pose_estimator    WHAM (3D human pose)                     estimate(image) -> HumanPose2D3D | None

The offline default backend of every role is named "synthetic" (lomanip_perception.synthetic): it
draws or reads a synthetic demonstration's ground truth with configurable corruption. Adapters for
the real models plug in under other names.
"""
from __future__ import annotations

from typing import Protocol, Sequence, runtime_checkable

import numpy as np

from .datatypes import Detection, GenerationRequest, HumanPose2D3D, MatchPool, PerceptionImage

ROLES = ("image_generator", "detector", "segmenter", "depth_estimator", "matcher", "pose_estimator")


@runtime_checkable
class ImageGenerator(Protocol):
    name: str

    def generate(self, request: GenerationRequest) -> PerceptionImage:
        """An RGB demonstration image R_g for the prompt (no depth, no camera model)."""


@runtime_checkable
class ObjectDetector(Protocol):
    name: str

    def detect(self, image: PerceptionImage, labels: Sequence[str]) -> list[Detection]:
        """Boxes for each open-vocabulary label found (best first); [] if none."""


@runtime_checkable
class Segmenter(Protocol):
    name: str

    def segment(self, image: PerceptionImage, detections: Sequence[Detection]) -> list[np.ndarray]:
        """One boolean (H, W) mask per detection box."""


@runtime_checkable
class DepthEstimator(Protocol):
    name: str

    def estimate(self, image: PerceptionImage) -> np.ndarray:
        """Metric depth (H, W) in metres along the optical axis."""


@runtime_checkable
class SemanticMatcher(Protocol):
    name: str

    def match(self, source: PerceptionImage, source_mask: np.ndarray, query_uv: np.ndarray,
              target: PerceptionImage, target_mask: np.ndarray, top_n: int) -> MatchPool:  # fmt: skip
        """Top-N candidate target pixels (inside target_mask) for each query pixel of the source."""


@runtime_checkable
class HumanPoseEstimator(Protocol):
    name: str

    def estimate(self, image: PerceptionImage) -> HumanPose2D3D | None:
        """The most prominent person's pose, or None when no person is found."""
