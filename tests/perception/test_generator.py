"""Synthetic demonstrations: an adult person touching another instance of the object where the
prompt says, from a random viewpoint, with a camera the pipeline is not told."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.datatypes import GenerationRequest
from lomanip_perception.prompts import generation_prompt, parse_subtask
from lomanip_perception.scene import ObjectGeometry
from lomanip_perception.synthetic.generator import PERSON, SyntheticImageGenerator
from lomanip_perception.synthetic.human import BodyDims

SCENE_SIZES = {"box": (0.4, 0.4, 0.3), "shelf": (0.4, 0.8, 1.5), "basket": (0.3, 0.4, 0.25),
               "table": (0.6, 0.8, 0.7), "trolley": (0.8, 0.5, 0.866)}
CLASSES = {"box", "shelf", "basket", "table", "trolley"}


def _demo(prompt, seed, size=512, **kw):
    st = parse_subtask(0, prompt, CLASSES)
    gen = SyntheticImageGenerator(**kw)
    return gen.generate(GenerationRequest(generation_prompt(prompt), seed, st, size, size, SCENE_SIZES))


def _touching(gt, limb) -> tuple[ObjectGeometry, object]:
    c = next(c for c in gt.contacts if c.limb == limb)
    return gt.objects[c.object_name], c


def test_image_is_ldm_like_and_the_camera_stays_hidden():
    img = _demo("pick up the box", 1, size=1024)
    assert img.rgb.shape == (1024, 1024, 3) and img.rgb.dtype == np.uint8
    assert img.depth is None and img.camera is None and img.camera_pose is None  # like an LDM output
    gt = img.ground_truth
    assert 45.0 <= gt.fovy_deg <= 60.0 and gt.camera.width == 1024
    assert (gt.labels == PERSON).mean() > 0.03  # the person is a large part of the picture
    assert (gt.mask("box")).mean() > 0.01


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pick_up_the_box_hands_on_its_side_faces(seed):
    gt = _demo("pick up the box", seed).ground_truth
    assert gt.human_present and gt.reach_error <= 0.03
    P = gt.keypoints_world
    H = float(np.linalg.norm(P["left_hip"] - P["left_knee"]) / BodyDims(1.0).thigh)  # stature from the skeleton
    assert 1.60 <= H <= 1.90  # adult
    d = BodyDims(H)
    for a, b, length in [("left_knee", "left_ankle", d.shin), ("right_shoulder", "right_elbow", d.upper_arm),
                         ("right_elbow", "right_wrist", d.forearm)]:
        assert abs(np.linalg.norm(P[a] - P[b]) - length) < 1e-6
    box = gt.objects["box"]
    for limb in ("left_hand", "right_hand"):
        obj, c = _touching(gt, limb)
        assert obj.object_class == "box"
        assert abs(obj.signed_distance(c.point)[0][0]) < 1e-6  # on the surface
        assert abs(c.normal[2]) < 1e-6  # a side face, not the top
        assert np.linalg.norm(P[limb] - c.point) < 0.04  # the palm is there
    # the two hands are on opposite faces
    n = {c.limb: c.normal for c in gt.contacts}
    assert n["left_hand"] @ n["right_hand"] < -0.99
    # other instance: each side within +-20 % of the scene's box, and not the same size
    size = 2 * box.bbox_local()[1]
    ratio = size / np.array(SCENE_SIZES["box"])
    assert np.all((ratio >= 0.8 - 1e-9) & (ratio <= 1.2 + 1e-9)) and not np.allclose(ratio, 1.0)


def test_instances_colours_yaws_and_viewpoints_vary():
    a, b = _demo("pick up the box", 10).ground_truth, _demo("pick up the box", 11).ground_truth
    oa, ob = a.objects["box"], b.objects["box"]
    assert oa.primitives[0].rgba != ob.primitives[0].rgba
    assert not np.allclose(oa.quat, ob.quat)
    assert not np.allclose(a.camera_pose.t - oa.pos, b.camera_pose.t - ob.pos)
    assert a.fovy_deg != b.fovy_deg


def test_step_on_the_box_and_grab_the_basket():
    gt = _demo("step on the box and grab the basket", 3).ground_truth
    assert set(gt.objects) == {"box", "basket", "shelf"}  # the basket sits on a shelf
    for limb in ("left_foot", "right_foot"):
        obj, c = _touching(gt, limb)
        assert obj.object_class == "box" and np.allclose(c.normal, [0, 0, 1])
        assert abs(c.point[2] - (obj.pos[2] + obj.bbox_local()[1][2])) < 1e-6  # on the top
    for limb in ("left_hand", "right_hand"):
        obj, c = _touching(gt, limb)
        assert obj.object_class == "basket" and abs(obj.signed_distance(c.point)[0][0]) < 1e-6
        top = obj.pos[2] + 2 * obj.bbox_local()[1][2]
        assert top - 0.09 < c.point[2] < top  # near the rim
        # in the walls' half nearer the person (who lifts it towards themselves)
        centre = obj.pos + obj.R @ obj.bbox_local()[0]
        towards_basket = (centre - gt.keypoints_world["pelvis"])[:2]
        assert (c.point - centre)[:2] @ towards_basket / np.linalg.norm(towards_basket) < -0.03


def test_push_the_trolley_hands_on_the_handle():
    gt = _demo("push the trolley forward", 4).ground_truth
    tro = gt.objects["trolley"]
    bar = tro.primitives[3]
    for limb in ("left_hand", "right_hand"):
        _, c = _touching(gt, limb)
        q = (tro.to_local(c.point)[0] - bar.pos) @ bar.R
        assert abs(np.hypot(q[0], q[1]) - bar.size[0]) < 1e-6 and abs(q[2]) < bar.size[1]
    # the person stands behind the handle (local -x), facing +x
    pel = tro.to_local(gt.keypoints_world["pelvis"])[0]
    assert pel[0] < bar.pos[0]


def test_place_on_the_trolley_puts_the_box_on_its_deck():
    gt = _demo("place the box on the trolley", 5).ground_truth
    box, tro = gt.objects["box"], gt.objects["trolley"]
    deck = tro.primitives[0]
    deck_top = tro.pos[2] + deck.pos[2] + deck.size[2]
    assert abs((box.pos[2] - box.bbox_local()[1][2]) - deck_top) < 1e-6


def test_without_person():
    img = _demo("pick up the box", 6, size=256, with_person=False)
    assert not img.ground_truth.human_present and not (img.ground_truth.labels == PERSON).any()
