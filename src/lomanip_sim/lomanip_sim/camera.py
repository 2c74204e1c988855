"""Headless RGB-D rendering of the fixed scene camera, with ROS-style intrinsics and poses.

Why: perception needs the simulated RGB-D frame R_s, D_s and the *correct* intrinsics (paper
Sec. III-A2). Rendering runs on its OWN MjData: the caller hands in a qpos snapshot (see
``Simulation.snapshot``), this module runs kinematics on its copy and renders, so rendering never
blocks or perturbs physics.

Conventions (as sensor_msgs/Image + CameraInfo expect):

* ``rgb``: uint8 (H, W, 3), row 0 at the top; ``depth``: float32 (H, W), metres along the optical
  axis (z of the optical frame, not the ray length); pixels that hit nothing are +inf (REP 118).
* intrinsics in the optical frame (x right, y down, z forward), pixel centres at integer
  coordinates: fx = fy = (H/2) / tan(fovy/2), cx = (W-1)/2, cy = (H-1)/2.
* poses: the MuJoCo camera frame (looks along -z, y up) and the ROS optical frame
  (``frames.R_MJCAM_TO_OPTICAL``), both in the world.

Headless GL: MuJoCo picks its GL backend from ``MUJOCO_GL`` when ``mujoco`` is first imported.
:func:`select_gl_backend` (called by ``lomanip_sim/__init__``) sets ``egl`` (or ``osmesa`` if only
OSMesa exists) unless the user already chose one. On these machines EGL works on Mesa's CPU
renderer; OSMesa needs the Debian package libosmesa6.
"""

from __future__ import annotations

import ctypes.util
import os
import sys
from dataclasses import dataclass

import numpy as np

from . import frames


class CameraError(RuntimeError):
    """The camera is missing from the model or no GL context could be created."""


def select_gl_backend(default: str | None = None) -> str | None:
    """Set MUJOCO_GL (and PYOPENGL_PLATFORM) for headless rendering unless the user set it.

    Returns the backend in effect. Must run before ``mujoco`` is imported to have any effect; if
    mujoco was already imported the environment is left alone.
    """
    current = os.environ.get("MUJOCO_GL")
    if current:
        return current
    if "mujoco" in sys.modules:
        return None
    choice = default
    if choice is None:
        if ctypes.util.find_library("EGL"):
            choice = "egl"
        elif ctypes.util.find_library("OSMesa"):
            choice = "osmesa"
        else:
            return None  # leave MuJoCo's default (GLFW, needs a display)
    os.environ["MUJOCO_GL"] = choice
    if choice in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", choice)
    return choice


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics in the ROS optical frame convention (no distortion)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    fovy_deg: float

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def P(self) -> np.ndarray:
        """3x4 projection matrix as in sensor_msgs/CameraInfo."""
        return np.hstack([self.K, np.zeros((3, 1))])

    def project(self, p_optical: np.ndarray) -> np.ndarray:
        """Pixel (u, v) of a point given in the optical frame (z > 0)."""
        p = np.asarray(p_optical, dtype=float)
        return np.array([self.fx * p[0] / p[2] + self.cx, self.fy * p[1] / p[2] + self.cy])

    def backproject(self, u: float, v: float, depth: float) -> np.ndarray:
        """Optical-frame point at pixel (u, v) with depth along the optical axis."""
        return np.array([(u - self.cx) / self.fx * depth, (v - self.cy) / self.fy * depth, depth])


def intrinsics_from_fovy(width: int, height: int, fovy_deg: float) -> CameraIntrinsics:
    """MuJoCo cameras have square pixels and a vertical field of view ``fovy``."""
    fy = 0.5 * height / np.tan(np.deg2rad(fovy_deg) / 2.0)
    return CameraIntrinsics(int(width), int(height), float(fy), float(fy), (width - 1) / 2.0, (height - 1) / 2.0,
                            float(fovy_deg))  # fmt: skip


@dataclass(frozen=True)
class CameraPose:
    """A camera pose in the world: MuJoCo camera frame and ROS optical frame (same origin)."""

    position: np.ndarray  # (3,)
    R_mujoco: np.ndarray  # (3,3) MuJoCo camera axes in the world (looks along -z)
    R_optical: np.ndarray  # (3,3) optical axes in the world (x right, y down, z forward)

    @property
    def quat_mujoco_wxyz(self) -> np.ndarray:
        return frames.matrix_to_quat(self.R_mujoco)

    @property
    def quat_optical_wxyz(self) -> np.ndarray:
        return frames.matrix_to_quat(self.R_optical)

    @property
    def quat_optical_xyzw(self) -> np.ndarray:
        """For geometry_msgs/Pose of the optical frame."""
        return frames.wxyz_to_xyzw(self.quat_optical_wxyz)

    def world_to_optical(self, p_world: np.ndarray) -> np.ndarray:
        return self.R_optical.T @ (np.asarray(p_world, dtype=float) - self.position)


@dataclass(frozen=True)
class RGBDFrame:
    """One rendered frame."""

    time: float
    rgb: np.ndarray  # uint8 (H, W, 3)
    depth: np.ndarray  # float32 (H, W), metres along the optical axis, +inf where nothing was hit
    intrinsics: CameraIntrinsics
    pose: CameraPose


class RGBDCamera:
    """Renders a fixed camera of a model from qpos snapshots, on its own MjData and GL context.

    Colour and depth come from ONE render pass (``mjr_readPixels`` reads both buffers), which is
    twice as fast as mujoco.Renderer's separate colour and depth passes on a CPU GL renderer.
    The GL context belongs to the thread that creates the camera: create and use it there.
    """

    def __init__(self, model, camera_name: str = "scene_camera", width: int | None = None, height: int | None = None):
        import mujoco

        self._mj = mujoco
        self.model = model
        self.cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera_name)
        if self.cam_id < 0:
            raise CameraError(f"camera {camera_name!r} not found in the model")
        self.camera_name = camera_name
        res = model.cam_resolution[self.cam_id]
        self.width = int(width or (res[0] if res[0] > 1 else 640))
        self.height = int(height or (res[1] if res[1] > 1 else 480))
        if self.width > model.vis.global_.offwidth or self.height > model.vis.global_.offheight:
            raise CameraError(
                f"{self.width}x{self.height} exceeds the offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight} (set camera_width/height in the scenario)"
            )
        self.data = mujoco.MjData(model)
        self._gl = None
        try:
            self._gl = mujoco.GLContext(self.width, self.height)
            self._gl.make_current()
            self._con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
            self._con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # reversed Z: precise far away
        except Exception as e:  # GL init failures surface as various exception types
            raise CameraError(
                f"cannot create an offscreen GL context (MUJOCO_GL={os.environ.get('MUJOCO_GL', '<unset>')}): {e}. "
                "Headless: set MUJOCO_GL=egl (libegl1) or MUJOCO_GL=osmesa (libosmesa6) before importing mujoco"
            ) from e
        self._scene = mujoco.MjvScene(model, maxgeom=10000)
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = self.cam_id
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        for f in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX,
                  mujoco.mjtRndFlag.mjRND_FOG, mujoco.mjtRndFlag.mjRND_HAZE):  # fmt: skip
            self._scene.flags[f] = False
        self.intrinsics = intrinsics_from_fovy(self.width, self.height, float(model.cam_fovy[self.cam_id]))
        extent = float(model.stat.extent)
        self._near = float(model.vis.map.znear) * extent
        self._far = float(model.vis.map.zfar) * extent
        self._time = 0.0
        self._rgb = np.empty((self.height, self.width, 3), np.uint8)
        self._zbuf = np.empty((self.height, self.width), np.float32)

    def set_state(self, qpos: np.ndarray, time: float = 0.0) -> None:
        """Copy a qpos snapshot in and update kinematics (the only physics this class runs)."""
        q = np.asarray(qpos, dtype=float)
        if q.shape != (self.model.nq,):
            raise CameraError(f"qpos has shape {q.shape}, the model needs ({self.model.nq},)")
        self.data.qpos[:] = q
        self.data.time = time
        self._time = time
        self._mj.mj_kinematics(self.model, self.data)
        self._mj.mj_camlight(self.model, self.data)
        self._mj.mjv_updateScene(self.model, self.data, self._option, None, self._camera,
                                 self._mj.mjtCatBit.mjCAT_ALL, self._scene)

    def pose(self) -> CameraPose:
        """World pose of the camera for the current state."""
        p = self.data.cam_xpos[self.cam_id].copy()
        R = self.data.cam_xmat[self.cam_id].reshape(3, 3).copy()
        _, R_opt = frames.mujoco_camera_to_optical(p, R)
        return CameraPose(p, R, R_opt)

    def _render_pass(self, rgb: bool, depth: bool) -> tuple[np.ndarray | None, np.ndarray | None]:
        if self._gl is None:
            raise CameraError("render called after close")
        self._gl.make_current()
        self._mj.mjr_render(self._rect, self._scene, self._con)
        self._mj.mjr_readPixels(self._rgb if rgb else None, self._zbuf if depth else None, self._rect, self._con)
        colour = np.flipud(self._rgb).copy() if rgb else None  # GL rows start at the bottom
        metric = self._metric_depth(np.flipud(self._zbuf)) if depth else None
        return colour, metric

    def _metric_depth(self, zbuf: np.ndarray) -> np.ndarray:
        """Reversed-Z depth buffer (1 at near, 0 at far) -> metres along the optical axis."""
        near, far = np.float32(self._near), np.float32(self._far)
        c = -(far + near) / (far - near)
        d = -(np.float32(2) * far * near) / (far - near)
        c = np.float32(-0.5) * c - np.float32(0.5)
        d = np.float32(-0.5) * d
        depth = (d / (zbuf.astype(np.float64) + c)).astype(np.float32)
        depth[depth >= 0.999 * far] = np.inf
        return depth

    def render_rgb(self) -> np.ndarray:
        return self._render_pass(True, False)[0]

    def render_depth(self) -> np.ndarray:
        return self._render_pass(False, True)[1]

    def render(self, qpos: np.ndarray | None = None, time: float | None = None, rgb: bool = True,
               depth: bool = True) -> RGBDFrame:  # fmt: skip
        """Render RGB and/or depth for ``qpos`` (or the last state set). Skipped parts are empty arrays."""
        if qpos is not None:
            self.set_state(qpos, self._time if time is None else time)
        c, d = self._render_pass(rgb, depth)
        c = c if c is not None else np.zeros((0, 0, 3), np.uint8)
        d = d if d is not None else np.zeros((0, 0), np.float32)
        return RGBDFrame(self._time, c, d, self.intrinsics, self.pose())

    def close(self) -> None:
        gl, self._gl = getattr(self, "_gl", None), None
        if gl is not None:
            try:
                gl.make_current()
                self._con.free()
            finally:
                gl.free()

    def __enter__(self) -> "RGBDCamera":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
