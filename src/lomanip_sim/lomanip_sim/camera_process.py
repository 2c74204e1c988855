"""The RGB-D camera rendered in a worker process: :class:`RGBDCameraProcess`.

Why: MuJoCo renders on Mesa's CPU renderer here, 40-200 ms per RGB-D frame on 2 cores (with the
load and Mesa's thread count). Rendered on a thread of the simulator's process, the camera at 15 Hz
competed with the physics and control thread for the CPU and Python's GIL: the push executed in
the graph at a real-time factor of 0.36, against 0.63 with the camera at 0.5 Hz (session 25). In
its own process the render only shares the CPU, and Mesa is held to ``render_threads`` threads so
that a core stays with physics.

Same interface as :class:`~lomanip_sim.camera.RGBDCamera` for what the sim node uses: ``render``,
``intrinsics``, ``close``. Frames come back through shared memory, one frame at a time.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from multiprocessing import shared_memory
from multiprocessing.connection import Connection

import numpy as np

from .camera import CameraError, CameraPose, RGBDCamera, RGBDFrame

#: seconds to wait for the worker to start (import MuJoCo, build its GL context) or to render a frame
START_TIMEOUT = 60.0
FRAME_TIMEOUT = 30.0


def _serve(conn) -> None:
    """Worker process: build the camera from the first message, then render each (qpos, time)
    request into the shared buffer and answer with the frame's time and camera pose."""
    model, camera_name, width, height, shm_name = conn.recv()
    try:
        cam = RGBDCamera(model, camera_name, width, height)
    except Exception as e:  # noqa: BLE001 - reported to the parent, which raises CameraError
        conn.send(("error", f"{type(e).__name__}: {e}"))
        return
    shm = shared_memory.SharedMemory(name=shm_name)
    try:  # the parent owns the segment: this process's resource tracker must not unlink it at exit
        from multiprocessing import resource_tracker

        resource_tracker.unregister(shm._name, "shared_memory")  # noqa: SLF001
    except Exception:  # noqa: BLE001 - tracker internals differ between Python versions
        pass
    h, w = cam.height, cam.width
    rgb = np.ndarray((h, w, 3), np.uint8, buffer=shm.buf, offset=0)
    depth = np.ndarray((h, w), np.float32, buffer=shm.buf, offset=h * w * 3)
    conn.send(("ready", cam.intrinsics))
    try:
        while True:
            msg = conn.recv()
            if msg is None:
                break
            qpos, t = msg
            try:
                frame = cam.render(qpos, t)
            except Exception as e:  # noqa: BLE001
                conn.send(("error", f"{type(e).__name__}: {e}"))
                continue
            rgb[:] = frame.rgb
            depth[:] = frame.depth
            conn.send(("frame", (frame.time, frame.pose.position, frame.pose.R_mujoco, frame.pose.R_optical)))
    except (EOFError, OSError, KeyboardInterrupt):
        pass  # the parent is gone
    finally:
        del rgb, depth
        shm.close()
        cam.close()


def main() -> None:
    """``python -m lomanip_sim.camera_process FD``: serve the connection on socket FD."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole group: the parent closes us
    _serve(Connection(int(sys.argv[1])))


class RGBDCameraProcess:
    """A fixed camera of ``model`` rendered by a worker process (see the module docstring).

    ``render_threads``: Mesa's render threads in the worker (``LP_NUM_THREADS``; 0 = Mesa's default,
    one per core). Not thread-safe: one caller renders at a time (the sim node's render thread).
    """

    def __init__(self, model, camera_name: str = "scene_camera", width: int | None = None,
                 height: int | None = None, render_threads: int = 1):  # fmt: skip
        import mujoco

        cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera_name)
        if cam_id < 0:
            raise CameraError(f"camera {camera_name!r} not found in the model")
        res = model.cam_resolution[cam_id]
        self.width = int(width or (res[0] if res[0] > 1 else 640))
        self.height = int(height or (res[1] if res[1] > 1 else 480))
        self.nq = int(model.nq)
        nbytes = self.width * self.height * (3 + 4)
        self._proc = None
        self._shm = shared_memory.SharedMemory(create=True, size=nbytes)
        # a plain child process on one end of a socket pair (multiprocessing's spawn would re-import
        # the parent's main module, rclpy and all; fork is unsafe beside DDS threads)
        ours, theirs = socket.socketpair()
        env = dict(os.environ)
        if render_threads > 0:
            env.setdefault("LP_NUM_THREADS", str(int(render_threads)))  # Mesa llvmpipe's render threads
        try:
            self._proc = subprocess.Popen([sys.executable, "-m", "lomanip_sim.camera_process", str(theirs.fileno())],
                                          pass_fds=[theirs.fileno()], env=env)
        finally:
            theirs.close()
        self._conn = Connection(ours.detach())
        self._conn.send((model, camera_name, self.width, self.height, self._shm.name))
        kind, payload = self._receive(START_TIMEOUT, "start")
        if kind != "ready":
            self.close()
            raise CameraError(f"camera worker failed to start: {payload}")
        self.intrinsics = payload
        h, w = self.height, self.width
        self._rgb = np.ndarray((h, w, 3), np.uint8, buffer=self._shm.buf, offset=0)
        self._depth = np.ndarray((h, w), np.float32, buffer=self._shm.buf, offset=h * w * 3)

    def _receive(self, timeout: float, what: str):
        proc = self._proc
        if not self._conn.poll(timeout):
            code = proc.poll()
            self.close()
            raise CameraError(f"camera worker gave no answer to {what} within {timeout:.0f} s"
                              + ("" if code is None else f" (it exited with code {code})"))
        try:
            return self._conn.recv()
        except (EOFError, OSError) as e:
            self.close()
            raise CameraError(f"camera worker exited during {what} (code {proc.wait(5.0)})") from e

    def render(self, qpos: np.ndarray, time: float = 0.0) -> RGBDFrame:
        """RGB and depth for the state ``qpos`` (copied out of the shared buffer)."""
        if self._proc is None:
            raise CameraError("render called after close")
        q = np.asarray(qpos, dtype=float)
        if q.shape != (self.nq,):
            raise CameraError(f"qpos has shape {q.shape}, the model needs ({self.nq},)")
        self._conn.send((q, float(time)))
        kind, payload = self._receive(FRAME_TIMEOUT, "a frame")
        if kind != "frame":
            raise CameraError(f"camera worker: {payload}")
        t, p, R_mj, R_opt = payload
        return RGBDFrame(float(t), self._rgb.copy(), self._depth.copy(), self.intrinsics, CameraPose(p, R_mj, R_opt))

    def close(self) -> None:
        proc, self._proc = getattr(self, "_proc", None), None
        if proc is not None:
            try:
                self._conn.send(None)
            except (OSError, ValueError):
                pass
            try:
                proc.wait(5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5.0)
        conn = getattr(self, "_conn", None)
        if conn is not None:
            conn.close()
        shm, self._shm = getattr(self, "_shm", None), None
        if shm is not None:
            self._rgb = self._depth = None
            shm.close()
            try:
                shm.unlink()
            except FileNotFoundError:
                pass

    def __enter__(self) -> "RGBDCameraProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


if __name__ == "__main__":
    main()
