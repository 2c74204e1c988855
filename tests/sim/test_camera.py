"""camera: RGB-D frames with ROS-convention intrinsics: a known world point projects to the right
pixel and the depth there equals its distance along the optical axis; render rates are printed."""

import time

import numpy as np
import pytest

from lomanip_sim import frames
from lomanip_sim.camera import CameraError, RGBDCamera, intrinsics_from_fovy
from lomanip_sim.scenario import load_scenario
from lomanip_sim.simulator import Simulation


@pytest.fixture(scope="module")
def setup():
    sim = Simulation(load_scenario("s1_basket"))
    cam = RGBDCamera(sim.model)
    yield sim, cam
    cam.close()


def test_intrinsics_convention():
    k = intrinsics_from_fovy(640, 480, 60.0)
    assert k.fx == k.fy == pytest.approx(240.0 / np.tan(np.deg2rad(30.0)))
    assert (k.cx, k.cy) == (319.5, 239.5)
    assert k.K.shape == (3, 3) and k.P.shape == (3, 4)
    p = np.array([0.3, -0.2, 2.0])
    u, v = k.project(p)
    assert np.allclose(k.backproject(u, v, 2.0), p)


def test_frame_shapes_and_pose(setup):
    sim, cam = setup
    snap = sim.snapshot()
    f = cam.render(snap.qpos, snap.time)
    assert f.rgb.shape == (480, 640, 3) and f.rgb.dtype == np.uint8
    assert f.depth.shape == (480, 640) and f.depth.dtype == np.float32
    assert f.rgb.std() > 5  # not a blank image
    assert np.isfinite(f.depth[240:, :]).all()  # lower half sees the floor and objects
    p = sim.params
    assert np.allclose(f.pose.position, p.camera_position)
    fwd = np.asarray(p.camera_target) - np.asarray(p.camera_position)
    fwd /= np.linalg.norm(fwd)
    assert np.allclose(f.pose.R_optical[:, 2], fwd, atol=1e-6)  # optical z looks at the target
    assert np.allclose(f.pose.R_mujoco[:, 2], -fwd, atol=1e-6)
    assert np.allclose(frames.xyzw_to_wxyz(f.pose.quat_optical_xyzw), f.pose.quat_optical_wxyz)


@pytest.mark.parametrize("which", ["box_top_centre", "box_top_offset", "floor_point"])
def test_known_point_projects_and_depth_matches(setup, which):
    """Project a point of a horizontal surface; the depth at its pixel must match (1 cm) both the
    point's optical-axis distance and the exact ray/plane intersection through that pixel centre."""
    sim, cam = setup
    snap = sim.snapshot()
    f = cam.render(snap.qpos)
    box = sim.object_state("box")
    top = sim.params.box_size[2]
    if which == "box_top_centre":
        pw, plane_z = frames.transform_point(box.pos, box.quat, [0, 0, top / 2]), top
    elif which == "box_top_offset":
        pw, plane_z = frames.transform_point(box.pos, box.quat, [0.1, -0.12, top / 2]), top
    else:
        pw, plane_z = np.array([0.5, -0.8, 0.0]), 0.0
    po = f.pose.world_to_optical(pw)
    assert po[2] > 0
    u, v = f.intrinsics.project(po)
    iu, iv = int(round(u)), int(round(v))
    assert 0 <= iu < 640 and 0 <= iv < 480
    d = float(f.depth[iv, iu])
    # Exact expectation at the pixel centre: intersect its ray with the plane z = plane_z.
    ray_w = f.pose.R_optical @ f.intrinsics.backproject(iu, iv, 1.0)  # optical z component = 1
    s = (plane_z - f.pose.position[2]) / ray_w[2]
    print(f"\n{which}: pixel ({u:.2f}, {v:.2f}); optical depth of the point {po[2]:.4f} m; "
          f"ray/plane depth at pixel centre {s:.4f} m; rendered {d:.4f} m")
    assert abs(d - s) < 0.01
    assert abs(d - po[2]) < 0.01
    hit = f.pose.R_optical @ f.intrinsics.backproject(iu, iv, d) + f.pose.position
    assert abs(hit[2] - plane_z) < 0.01
    assert np.linalg.norm(hit[:2] - pw[:2]) < 0.02  # within ~a pixel footprint of the point


def test_render_rates(setup):
    sim, cam = setup
    snap = sim.snapshot()
    cam.set_state(snap.qpos)
    cam.render_rgb()
    n = 10
    t0 = time.perf_counter()
    for _ in range(n):
        cam.set_state(snap.qpos)
        cam.render_rgb()
    t1 = time.perf_counter()
    for _ in range(n):
        cam.set_state(snap.qpos)
        cam.render_depth()
    t2 = time.perf_counter()
    for _ in range(n):
        cam.render(sim.snapshot().qpos)
    t3 = time.perf_counter()
    print(f"\n640x480 render: rgb {n / (t1 - t0):.1f} fps, depth {n / (t2 - t1):.1f} fps, rgb+depth {n / (t3 - t2):.1f} fps")
    assert n / (t3 - t2) > 1.0


def test_bad_camera_and_qpos(setup):
    sim, cam = setup
    with pytest.raises(CameraError):
        RGBDCamera(sim.model, camera_name="nope")
    with pytest.raises(CameraError):
        cam.set_state(np.zeros(3))
    with pytest.raises(CameraError):
        RGBDCamera(sim.model, width=4096, height=4096)
