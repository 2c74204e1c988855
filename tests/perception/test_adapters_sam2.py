"""SAM 2 adapter: box prompts -> one boolean mask per detection, on a tiny random-weight Sam2Model."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.adapters.sam2 import Sam2Segmenter
from lomanip_perception.datatypes import Detection

from .test_adapters_common import noise_image, tiny_sam2


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tiny_sam2(tmp_path_factory.mktemp("sam2"))


def test_masks_per_box_at_image_size(folder):
    seg = Sam2Segmenter(path=str(folder), device="cpu", dtype="float32")
    img = noise_image(60, 90)
    dets = [Detection("box", (10.0, 10.0, 50.0, 40.0), 0.9), Detection("shelf", (0.0, 0.0, 89.0, 59.0), 0.5)]
    masks = seg.segment(img, dets)
    assert len(masks) == 2
    for m in masks:
        assert m.shape == (60, 90) and m.dtype == bool
    # clip_to_box: nothing further than the margin outside the first box
    v, u = np.nonzero(masks[0])
    if len(u):
        assert u.min() >= 10 - 5 and u.max() <= 50 + 5 and v.min() >= 10 - 5 and v.max() <= 40 + 5
    assert seg.segment(img, []) == []
    assert seg.size == 128 and "SAM 2" in seg.description


def test_unclipped_single_mask_output_and_bad_image(folder):
    seg = Sam2Segmenter(path=str(folder), device="cpu", multimask_output=False, clip_to_box=False)
    masks = seg.segment(noise_image(30, 20, seed=1), [Detection("box", (2.0, 3.0, 15.0, 25.0), 1.0)])
    assert masks[0].shape == (30, 20)
    from lomanip_perception.datatypes import PerceptionImage
    from lomanip_perception.errors import PerceptionError

    with pytest.raises(PerceptionError, match="HxWx3"):
        seg.segment(PerceptionImage(np.zeros((10, 10))), [Detection("box", (0, 0, 5, 5), 1.0)])
