"""Pictures of an executed run: video (MP4, or GIF without an MP4 encoder), PNG frames, plots.

Why: a run must be checked by eye, not only by numbers. The video is rendered offscreen AFTER the
run from the full-world qpos that the executor recorded at its log rate during the physics run
(so rendering never slows the controller). It shows the recorded physical motion, not the plan.
"""

from __future__ import annotations

import json
from pathlib import Path

import lomanip_sim  # noqa: F401  (headless GL backend before mujoco renders)
import mujoco
import numpy as np

from .trajectory import LIMBS


def _camera(model, qpos_frames: list[np.ndarray], base_q: int) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    xy = np.array([q[base_q : base_q + 2] for q in qpos_frames])
    lookat = np.array([*(0.5 * (xy.min(axis=0) + xy.max(axis=0))), 0.65])
    span = float(np.max(xy.max(axis=0) - xy.min(axis=0)))
    cam.lookat[:] = lookat + np.array([0.25, 0.0, 0.0])
    cam.distance = 2.6 + span
    cam.azimuth = 115.0  # from the robot's right, slightly in front: a table in front does not hide it
    cam.elevation = -15.0
    return cam


def render_frames(model, qpos_frames: list[np.ndarray], width: int = 640, height: int = 480, base_q: int = 0):
    """Yield RGB frames (H, W, 3) of the recorded states."""
    data = mujoco.MjData(model)
    cam = _camera(model, qpos_frames, base_q)
    with mujoco.Renderer(model, height, width) as r:
        for q in qpos_frames:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            r.update_scene(data, cam)
            yield r.render().copy()


def mp4_available() -> bool:
    """True when imageio can encode MP4 (its ffmpeg plugin, package imageio-ffmpeg, is installed)."""
    import importlib.util

    return importlib.util.find_spec("imageio_ffmpeg") is not None


def save_video(path: Path, model, qpos_frames, fps: float, width: int = 640, height: int = 480) -> Path:
    """MP4 when an encoder is installed, else an animated GIF (Pillow) next to ``path``; returns the file."""
    import imageio.v2 as imageio

    path = Path(path)
    if path.suffix == ".mp4" and mp4_available():
        with imageio.get_writer(path, fps=fps, codec="libx264", quality=7, macro_block_size=8) as w:
            for frame in render_frames(model, qpos_frames, width, height):
                w.append_data(frame)
        return path
    path = path.with_suffix(".gif")
    frames = list(render_frames(model, qpos_frames, width, height))
    imageio.mimsave(path, frames, duration=1000.0 / fps, loop=0)  # duration per frame in ms
    return path


def save_png_frames(out_dir: Path, model, qpos_frames, times, picks=(0.0, 0.33, 0.66, 1.0)) -> list[Path]:
    import imageio.v2 as imageio

    idx = sorted({min(int(p * (len(qpos_frames) - 1)), len(qpos_frames) - 1) for p in picks})
    chosen = [qpos_frames[i] for i in idx]
    paths = []
    for i, frame in zip(idx, render_frames(model, chosen)):
        p = Path(out_dir) / f"frame_t{times[i]:05.2f}.png"
        imageio.imwrite(p, frame)
        paths.append(p)
    return paths


def save_strip(path: Path, model, qpos_frames, picks=(0.0, 0.35, 0.6, 1.0), width: int = 400, height: int = 300) -> Path:
    """One PNG of a few recorded states side by side (for README pictures)."""
    import imageio.v2 as imageio

    idx = sorted({min(int(p * (len(qpos_frames) - 1)), len(qpos_frames) - 1) for p in picks})
    chosen = [qpos_frames[i] for i in idx]
    imageio.imwrite(path, np.concatenate(list(render_frames(model, chosen, width, height)), axis=1))
    return Path(path)


def save_plots(out_dir: Path, log, title: str = "") -> list[Path]:
    """tracking.png (base position and joint errors) and forces.png (normal forces, planned vs measured)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    t = np.asarray(log.t)
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax[0].plot(t, 100 * np.asarray(log.base_error))
    ax[0].set_ylabel("pelvis position error [cm]")
    ax[1].plot(t, np.asarray(log.joint_rms), label="RMS over 29 joints")
    ax[1].plot(t, np.asarray(log.joint_max), label="max joint")
    ax[1].set_ylabel("joint error [rad]")
    ax[1].set_xlabel("trajectory time [s]")
    ax[1].legend()
    fig.suptitle(f"tracking error {title}")
    fig.tight_layout()
    p1 = out_dir / "tracking.png"
    fig.savefig(p1, dpi=100)
    plt.close(fig)
    fig, ax = plt.subplots(len(LIMBS), 1, figsize=(8, 8), sharex=True)
    for a, limb in zip(ax, LIMBS):
        meas = np.asarray(log.measured[limb])
        plan = np.asarray(log.planned[limb])
        a.plot(t, np.linalg.norm(meas, axis=1), label="measured |f| (MuJoCo contacts)")
        a.plot(t, np.linalg.norm(plan, axis=1), "--", label="planned |f| (TO)")
        a.set_ylabel(f"{limb} [N]")
    ax[0].legend(fontsize=8)
    ax[-1].set_xlabel("trajectory time [s]")
    fig.suptitle(f"contact forces on the robot {title}")
    fig.tight_layout()
    p2 = out_dir / "forces.png"
    fig.savefig(p2, dpi=100)
    plt.close(fig)
    return [p1, p2]


def save_run(out_dir: Path, execution, name: str, video: bool = True) -> dict:
    """Video, frames, plots and metrics.json of a finished Execution under ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lg, model = execution.log, execution.sim.model
    files = {}
    files["plots"] = [str(p) for p in save_plots(out_dir, lg, name)]
    if video and lg.qpos:
        fps = execution.opt.log_rate
        mp4 = mp4_available()
        step = max(1, int(round(fps / (25.0 if mp4 else 12.5))))  # ~25 fps MP4, ~12.5 fps GIF (smaller)
        size = (640, 480) if mp4 else (400, 300)
        files["video"] = str(save_video(out_dir / "run.mp4", model, lg.qpos[::step], fps / step, *size))
        files["frames"] = [str(p) for p in save_png_frames(out_dir, model, lg.qpos, lg.t)]
        files["strip"] = str(save_strip(out_dir / "strip.png", model, lg.qpos))
    metrics = execution.metrics.as_dict() if execution.metrics else {}
    (out_dir / "metrics.json").write_text(json.dumps({"name": name, "metrics": metrics, "files": files}, indent=2))
    return files
