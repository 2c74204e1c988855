"""camera_process: the camera rendered by a worker process gives the in-process camera's frames,
refuses a wrong state, and a dead worker is a CameraError, not a hang."""

import numpy as np
import pytest

from lomanip_sim.camera import CameraError, RGBDCamera
from lomanip_sim.camera_process import RGBDCameraProcess
from lomanip_sim.scenario import load_scenario
from lomanip_sim.simulator import Simulation


@pytest.fixture(scope="module")
def sim():
    return Simulation(load_scenario("s2_trolley"))


def test_worker_frames_equal_in_process_frames(sim):
    sim.step(50)
    snap = sim.snapshot()
    local = RGBDCamera(sim.model, sim.world.camera_name)
    try:
        with RGBDCameraProcess(sim.model, sim.world.camera_name) as worker:
            a, b = local.render(snap.qpos, snap.time), worker.render(snap.qpos, snap.time)
            again = worker.render(snap.qpos, snap.time)  # the shared buffer is copied out, not aliased
    finally:
        local.close()
    assert b.rgb.std() > 5 and np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth, b.depth)
    assert b.time == pytest.approx(snap.time) and b.intrinsics == a.intrinsics
    assert np.allclose(b.pose.R_optical, a.pose.R_optical) and np.allclose(b.pose.position, a.pose.position)
    assert not np.shares_memory(again.rgb, b.rgb) and not np.shares_memory(again.depth, b.depth)


def test_wrong_state_and_dead_worker_raise(sim):
    worker = RGBDCameraProcess(sim.model, sim.world.camera_name)
    with pytest.raises(CameraError, match="qpos has shape"):
        worker.render(np.zeros(5))
    worker._proc.kill()  # noqa: SLF001 - the worker dies (e.g. killed by the OOM killer)
    with pytest.raises(CameraError, match="exited"):
        worker.render(sim.snapshot().qpos)
    worker.close()  # idempotent after the failure
    with pytest.raises(CameraError, match="after close"):
        worker.render(sim.snapshot().qpos)


def test_unknown_camera_is_refused(sim):
    with pytest.raises(CameraError, match="not found"):
        RGBDCameraProcess(sim.model, "no_such_camera")
