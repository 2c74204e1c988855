"""Florence-2 adapter: output parsing, and the real path (tokens, pixels, generate, decode, parse)
on a tiny random-weight model."""
from __future__ import annotations

import pytest

from lomanip_perception.adapters.florence2 import Florence2Detector, parse_florence_output
from lomanip_perception.datatypes import Detection

from .test_adapters_common import noise_image, tiny_florence2


def test_parse_open_vocabulary_boxes_to_pixels():
    text = "</s><s>box<loc_100><loc_200><loc_299><loc_499>box<loc_0><loc_0><loc_999><loc_999></s>"
    out = parse_florence_output(text, 1000, 500)
    assert [lb for lb, _ in out] == ["box", "box"]
    assert out[0][1] == pytest.approx((100.5, 100.25, 299.5, 249.75))
    assert out[1][1] == pytest.approx((0.5, 0.25, 999.0, 499.0))  # clipped to the image


def test_parse_polygons_labels_and_incomplete_groups():
    text = "shelf<poly><loc_10><loc_20><loc_50><loc_22><loc_40><loc_80></poly>basket<loc_1><loc_2><loc_3>"
    out = parse_florence_output(text, 100, 100)
    assert len(out) == 1 and out[0][0] == "shelf"
    assert out[0][1] == pytest.approx((1.05, 2.05, 5.05, 8.05))
    assert parse_florence_output("<loc_5><loc_5><loc_9><loc_9>", 100, 100, default_label="box")[0][0] == "box"
    assert parse_florence_output("nothing here", 100, 100) == []


@pytest.fixture(scope="module")
def detector(tmp_path_factory):
    folder = tiny_florence2(tmp_path_factory.mktemp("florence2"))
    return Florence2Detector(path=str(folder), device="cpu", dtype="float32", num_beams=2, max_new_tokens=24)


def test_real_path_on_tiny_model(detector):
    img = noise_image(48, 80)
    text, score = detector.answer(img, "Locate box in the image.")
    assert "<loc_" in text and 0.0 <= score <= 1.0  # a random model still speaks in location tokens
    dets = detector.detect(img, ["box", "basket"])
    assert all(isinstance(d, Detection) and d.label in ("box", "basket") for d in dets)
    for d in dets:
        x0, y0, x1, y1 = d.box
        assert 0 <= x0 < x1 <= 79 and 0 <= y0 < y1 <= 47
    assert detector.num_image_tokens == 2 * 2 + 1  # 64 px input, stride 32, + temporal token
    assert "Florence-2" in detector.description and "cpu" in detector.description


def test_decoding_real_tokens_parses_into_detections(detector):
    tok = detector.tokenizer
    ids = tok("box <loc_100> <loc_200> <loc_600> <loc_900>", add_special_tokens=False)["input_ids"]
    text = tok.decode([tok.eos_token_id, tok.bos_token_id] + ids + [tok.eos_token_id], skip_special_tokens=False)
    out = parse_florence_output(text, 80, 48)
    assert out[0][0] == "box" and out[0][1] == pytest.approx((8.04, 9.624, 48.04, 43.224))


def test_od_task_filters_labels(tmp_path_factory, detector):
    od = Florence2Detector(path=str(detector.folder), device="cpu", task="od", num_beams=1, max_new_tokens=12)
    assert od.model is detector.model  # same weights: one copy
    assert all(d.label == "box" for d in od.detect(noise_image(40, 40), ["box"]))
    with pytest.raises(ValueError):
        Florence2Detector(path=str(detector.folder), task="caption")
