"""Plain data types passed between the model roles and the contact transfer (numpy, no ROS).

Pixel convention everywhere: (u, v) = (column, row), pixel centres at integer coordinates, as in
sensor_msgs/CameraInfo. Camera frames are ROS optical frames (x right, y down, z forward).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PinholeCamera:
    """Distortion-free pinhole intrinsics."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @classmethod
    def paper_heuristic(cls, width: int, height: int) -> "PinholeCamera":
        """Paper Sec. III-A2 for generated images (no camera model): the image resolution as the
        focal lengths and half of it as the principal point."""
        return cls(int(width), int(height), float(width), float(height), width / 2.0, height / 2.0)

    @classmethod
    def from_fovy(cls, width: int, height: int, fovy_deg: float) -> "PinholeCamera":
        f = 0.5 * height / np.tan(np.deg2rad(fovy_deg) / 2.0)
        return cls(int(width), int(height), float(f), float(f), (width - 1) / 2.0, (height - 1) / 2.0)

    def backproject(self, u: np.ndarray, v: np.ndarray, z: np.ndarray) -> np.ndarray:
        """(N,3) optical-frame points of pixels (u, v) with depth z along the optical axis."""
        u, v, z = (np.asarray(a, dtype=float) for a in (u, v, z))
        return np.stack([(u - self.cx) / self.fx * z, (v - self.cy) / self.fy * z, z], axis=-1)

    def project(self, p: np.ndarray) -> np.ndarray:
        """(N,2) pixels of optical-frame points (N,3)."""
        p = np.atleast_2d(p)
        return np.stack([self.fx * p[:, 0] / p[:, 2] + self.cx, self.fy * p[:, 1] / p[:, 2] + self.cy], axis=-1)


@dataclass(frozen=True)
class RigidPose:
    """world_from_frame: p_world = R @ p_frame + t."""

    R: np.ndarray
    t: np.ndarray

    @classmethod
    def identity(cls) -> "RigidPose":
        return cls(np.eye(3), np.zeros(3))

    def apply(self, p: np.ndarray) -> np.ndarray:
        return np.atleast_2d(p) @ self.R.T + self.t

    def inverse_apply(self, p: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(p) - self.t) @ self.R


@dataclass
class PerceptionImage:
    """An image handed to the model roles.

    ``depth``/``camera``/``camera_pose`` are set for the simulated scene image R_s (true metric
    depth and intrinsics) and left empty for a generated image R_g. ``ground_truth`` is read ONLY by
    the synthetic stand-ins (the synthetic generator's record of what it drew, or the scene's known
    object geometry); real model adapters must ignore it.
    """

    rgb: np.ndarray
    depth: np.ndarray | None = None
    camera: PinholeCamera | None = None
    camera_pose: RigidPose | None = None
    ground_truth: Any = None
    source: str = ""  # e.g. "synthetic generator", "simulator"

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])


@dataclass(frozen=True)
class Detection:
    """An open-vocabulary detection: label, box (x0, y0, x1, y1) in pixels, score."""

    label: str
    box: tuple[float, float, float, float]
    score: float


@dataclass(frozen=True)
class MatchPool:
    """Semantic matcher output: for each query pixel of the source image, its top-N candidate
    pixels in the target image, best first (scores descending)."""

    query_uv: np.ndarray  # (M, 2) int
    candidates_uv: np.ndarray  # (M, N, 2) int
    scores: np.ndarray  # (M, N)


@dataclass(frozen=True)
class HumanPose2D3D:
    """A human pose from one image: 2D keypoints, their visibility, and 3D keypoints in that
    image's camera frame (metric as far as the estimator knows), plus joint angles."""

    keypoint_names: tuple[str, ...]
    uv: np.ndarray  # (K, 2)
    visibility: np.ndarray  # (K,) 0..1
    xyz_camera: np.ndarray  # (K, 3)
    joint_names: tuple[str, ...] = ()
    joint_angles: np.ndarray = field(default_factory=lambda: np.zeros(0))
    confidence: float = 1.0

    def index(self, name: str) -> int:
        return self.keypoint_names.index(name)


@dataclass(frozen=True)
class GenerationRequest:
    """What an image generator is asked for. A real text-to-image model reads ``prompt`` (the
    paper's template) and ``seed``; the synthetic generator also reads the parsed ``subtask`` and
    ``reference_sizes`` (class -> full bounding-box size of the scene's instance), so the benchmark
    controls the intra-class gap (+-20 %)."""

    prompt: str
    seed: int
    subtask: Any = None
    width: int = 1024
    height: int = 1024
    reference_sizes: dict = field(default_factory=dict)
