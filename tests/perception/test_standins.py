"""Synthetic stand-ins read the demo's ground truth with the configured corruption."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.datatypes import GenerationRequest, PerceptionImage
from lomanip_perception.errors import INVALID_REQUEST, PerceptionError
from lomanip_perception.prompts import generation_prompt, parse_subtask
from lomanip_perception.synthetic.generator import SyntheticImageGenerator
from lomanip_perception.synthetic.human import KEYPOINTS
from lomanip_perception.synthetic.standins import (SyntheticDepthEstimator, SyntheticDetector, SyntheticMatcher,
                                                   SyntheticPoseEstimator, SyntheticSegmenter)

CLASSES = {"box", "shelf", "basket", "table", "trolley"}


def _demo(prompt, seed, size=384, **kw):
    st = parse_subtask(0, prompt, CLASSES)
    return SyntheticImageGenerator(**kw).generate(GenerationRequest(generation_prompt(prompt), seed, st, size, size))


@pytest.fixture(scope="module")
def demos():
    return _demo("pick up the box", 1), _demo("pick up the box", 2)


def test_detector_and_segmenter_recover_the_object_mask(demos):
    img = demos[0]
    dets = SyntheticDetector().detect(img, ["box", "trolley"])
    assert [d.label for d in dets] == ["box"]
    mask = SyntheticSegmenter().segment(img, dets)[0]
    truth = img.ground_truth.mask("box")
    assert (mask & truth).sum() / (mask | truth).sum() > 0.85
    assert SyntheticDetector().detect(img, ["person"])[0].label == "person"


def test_depth_has_the_configured_scale_error_and_noise(demos):
    img = demos[0]
    true = img.ground_truth.depth
    fin = np.isfinite(true)
    est = SyntheticDepthEstimator(scale_error=0.1, noise=0.0).estimate(img)
    ratio = est[fin] / true[fin]
    assert np.allclose(ratio, ratio[0], rtol=1e-5) and abs(abs(ratio[0] - 1) - 0.1) < 1e-5
    noisy = SyntheticDepthEstimator(scale_error=0.0, noise=0.02).estimate(img)
    assert abs(np.std(noisy[fin] / true[fin]) - 0.02) < 0.003
    assert np.all(np.isfinite(noisy))  # background gets a far depth, like a real estimator


def _canon(img, mask_name, uv):
    gt = img.ground_truth
    return gt.objects[mask_name].canonical(gt.world_points(uv[:, 0], uv[:, 1]))


def test_matcher_outlier_rate_flips_and_pool(demos):
    src, tgt = demos
    ms, mt = src.ground_truth.mask("box"), tgt.ground_truth.mask("box")
    v, u = np.nonzero(ms)
    q = np.column_stack([u, v])[np.random.default_rng(0).choice(len(u), 400, replace=False)]
    cq = _canon(src, "box", q)
    tv, tu = np.nonzero(mt)
    c_all = _canon(tgt, "box", np.column_stack([tu, tv]))

    def best_visible(c):  # the closest the target view can get to canonical points c
        return c_all[np.argmin(((c[:, None] - c_all[None]) ** 2).sum(-1), axis=1)]

    right, mirrored = best_visible(cq), best_visible(cq * [1, -1, 1])

    def top(matcher):
        pool = matcher.match(src, ms, q, tgt, mt, 5)
        assert pool.candidates_uv.shape == (400, 5, 2) and np.all(np.diff(pool.scores, axis=1) <= 0)
        assert np.all(mt[pool.candidates_uv[..., 1], pool.candidates_uv[..., 0]])  # inside the target mask
        return pool, [_canon(tgt, "box", pool.candidates_uv[:, k]) for k in range(5)]

    def near(c, ref):
        return np.linalg.norm(c - ref, axis=1) < 0.2

    _, c = top(SyntheticMatcher(outlier_rate=0.0, noise=0.02))
    assert near(c[0], right).mean() > 0.9
    _, c = top(SyntheticMatcher(outlier_rate=0.4, noise=0.02))
    assert 0.5 < near(c[0], right).mean() < 0.75  # about 40 % outliers (some land near the truth by chance)
    # flips: the best candidate is the left/right mirror image of the query
    _, c = top(SyntheticMatcher(outlier_rate=1.0, flip_fraction=1.0, noise=0.02))
    side = np.abs(cq[:, 1]) > 0.5
    assert near(c[0], mirrored)[side].mean() > 0.85 and near(c[0], right)[side].mean() < 0.2
    # the true match stays in the pool of about true_in_pool_when_outlier of the outliers
    _, c = top(SyntheticMatcher(outlier_rate=1.0, flip_fraction=1.0, true_in_pool_when_outlier=0.6, noise=0.02))
    in_pool = np.any([near(ck, right) for ck in c], axis=0)
    assert in_pool[side].mean() > 0.45  # (the pool also holds a near-miss candidate)
    with pytest.raises(ValueError):
        SyntheticMatcher(outlier_rate=1.5)


def test_pose_noise_and_no_person(demos):
    img = demos[0]
    gt = img.ground_truth
    pose = SyntheticPoseEstimator(joint_noise_px=3.0, joint_noise_m=0.02).estimate(img)
    assert pose.keypoint_names == KEYPOINTS and len(pose.joint_angles) == len(pose.joint_names)
    cam = gt.camera_pose.inverse_apply(np.stack([gt.keypoints_world[k] for k in KEYPOINTS]))
    assert 1.0 < np.std(pose.uv - gt.camera.project(cam)) < 5.0
    assert 0.01 < np.std(pose.xyz_camera - cam) < 0.03
    exact = SyntheticPoseEstimator(joint_noise_px=0.0, joint_noise_m=0.0).estimate(img)
    assert np.allclose(exact.xyz_camera, cam)
    assert SyntheticPoseEstimator().estimate(_demo("pick up the box", 3, size=128, with_person=False)) is None


def test_stand_ins_refuse_images_without_ground_truth():
    img = PerceptionImage(np.zeros((8, 8, 3), np.uint8))
    for call in (lambda: SyntheticDetector().detect(img, ["box"]), lambda: SyntheticPoseEstimator().estimate(img),
                 lambda: SyntheticDepthEstimator().estimate(img)):
        with pytest.raises(PerceptionError) as e:
            call()
        assert e.value.code == INVALID_REQUEST
