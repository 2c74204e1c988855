"""ViTPose adapter: crop warp, heatmap decoding, lomanip keypoints, 3D lifting with the metric depth
backend and joint angles, on tiny random-weight ViTPose and Depth Anything V2 models."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception import registry
from lomanip_perception.adapters.vitpose import JOINT_NAMES, KEYPOINTS, crop_affine, joint_angles, refine_argmax
from lomanip_perception.datatypes import Detection, HumanPose2D3D, PinholeCamera
from lomanip_perception.errors import PerceptionError

from .test_adapters_common import noise_image, tiny_depth_anything, tiny_vitpose


def test_refine_argmax_and_crop_affine():
    hm = np.zeros((1, 8, 6))
    hm[0, 3, 2], hm[0, 3, 3] = 1.0, 0.5
    xy, s = refine_argmax(hm)
    assert xy[0] == pytest.approx((2.25, 3.0)) and s[0] == 1.0
    A = crop_affine((10, 20, 30, 100), (256, 192), 1.25)
    centre = A @ np.array([20.0, 60.0, 1.0])
    assert centre == pytest.approx((96.0, 128.0))
    assert A[0, 0] == pytest.approx(256 / (80 * 1.25))  # tall box: height sets the scale


def test_joint_angles_of_a_standing_person():
    P = {"pelvis": np.array([0, 0, 3.0]), "neck": np.array([0, -0.5, 3.0])}
    for side, x in (("left", 0.1), ("right", -0.1)):
        P.update({f"{side}_hip": np.array([x, 0, 3.0]), f"{side}_knee": np.array([x, 0.45, 3.0]),
                  f"{side}_ankle": np.array([x, 0.9, 3.0]), f"{side}_shoulder": np.array([x * 2, -0.5, 3.0]),
                  f"{side}_elbow": np.array([x * 2, -0.2, 3.0]), f"{side}_wrist": np.array([x * 2, 0.05, 3.0])})
    assert joint_angles(P) == pytest.approx(np.zeros(len(JOINT_NAMES)), abs=1e-6)
    P["left_knee"] = np.array([0.1, 0.0, 2.55])  # thigh horizontal, forward; shin vertical
    P["left_ankle"] = np.array([0.1, 0.45, 2.55])
    a = joint_angles(P)
    assert a[0] == pytest.approx(-np.pi / 2) and a[1] == pytest.approx(np.pi / 2)


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    return (tiny_vitpose(tmp_path_factory.mktemp("vitpose")), tiny_vitpose(tmp_path_factory.mktemp("vitwb"), 133),
            tiny_depth_anything(tmp_path_factory.mktemp("dav2")))


def _build(folder, depth, **kw):
    return registry.build("pose_estimator", "vitpose", {"path": str(folder), "device": "cpu", "min_confidence": 0.0,
                          "depth": {"backend": "depth_anything_v2", "params": {"path": str(depth), "device": "cpu",
                                                                                "input_size": 56}}, **kw})


def test_pose_from_image_lifted_with_depth(folders):
    coco, _, depth = folders
    est = _build(coco, depth)
    img = noise_image(96, 64)
    pose = est.estimate(img)
    assert isinstance(pose, HumanPose2D3D) and pose.keypoint_names == KEYPOINTS
    assert pose.uv.shape == (24, 2) and pose.xyz_camera.shape == (24, 3) and pose.visibility.shape == (24,)
    z = est.depth.estimate(img)
    i = pose.index("left_hip")
    u, v = np.clip(np.round(pose.uv[i]).astype(int), 0, [63, 95])
    assert pose.xyz_camera[i, 2] == pytest.approx(float(np.median(z[max(0, v - 2):v + 3, max(0, u - 2):u + 3])) + 0.08,
                                                  rel=1e-4)  # fmt: skip
    cam = PinholeCamera.paper_heuristic(64, 96)
    assert cam.project(pose.xyz_camera) == pytest.approx(pose.uv, abs=1e-6)  # back-projected along the pixel ray
    assert pose.xyz_camera[pose.index("pelvis")] == pytest.approx(
        cam.backproject(*pose.uv[pose.index("pelvis")], pose.xyz_camera[pose.index("pelvis"), 2]))
    assert pose.joint_names == JOINT_NAMES and pose.joint_angles.shape == (9,) and np.isfinite(pose.joint_angles).all()
    assert "depth_anything_v2" in est.description


def test_wholebody_layout_uses_foot_points(folders):
    _, wb, depth = folders
    pose = _build(wb, depth).estimate(noise_image(64, 64, 3))
    foot, ankle = pose.uv[pose.index("left_foot")], pose.uv[pose.index("left_ankle")]
    assert pose.uv.shape == (24, 2) and not np.allclose(foot, ankle)


class _NoPerson:
    name = "test-double"

    def detect(self, image, labels):
        return []


class _OnePerson(_NoPerson):
    def detect(self, image, labels):
        return [Detection("person", (5.0, 5.0, 40.0, 90.0), 0.9)]


def test_person_detector_gates_and_boxes(folders):
    coco, _, depth = folders
    est = _build(coco, depth)
    est.detector = _NoPerson()
    assert est.estimate(noise_image(96, 64)) is None  # NO_HUMAN_FOUND upstream
    est.detector = _OnePerson()
    assert est.estimate(noise_image(96, 64)) is not None
    est.detector, est.min_confidence = None, 1.01
    assert est.estimate(noise_image(96, 64)) is None


def test_depth_backend_is_required(folders):
    with pytest.raises(PerceptionError, match="params.depth"):
        registry.build("pose_estimator", "vitpose", {"path": str(folders[0]), "device": "cpu"})
