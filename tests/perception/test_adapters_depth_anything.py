"""Depth Anything V2 metric adapter: DPT-style preprocessing without torchvision, metric output at
image size, relative checkpoints refused, one model copy shared between roles."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.adapters.depth_anything import DepthAnythingV2Estimator, dpt_size
from lomanip_perception.errors import ModelUnavailableError

from .test_adapters_common import noise_image, tiny_depth_anything


def test_dpt_size_lower_bound_multiple_of_patch():
    assert dpt_size(1024, 1024, 518, 14) == (518, 518)
    h, w = dpt_size(480, 640, 518, 14)
    assert h % 14 == 0 and w % 14 == 0 and h >= 518 and w >= 518 * 640 / 480 - 14


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tiny_depth_anything(tmp_path_factory.mktemp("dav2"))


def test_metric_depth_at_image_size(folder):
    est = DepthAnythingV2Estimator(path=str(folder), device="cpu", input_size=56)
    img = noise_image(60, 90)
    z = est.estimate(img)
    assert z.shape == (60, 90) and z.dtype == np.float32
    assert np.isfinite(z).all() and (z > 0).all() and z.max() <= 20.0 + 1e-3  # sigmoid x max_depth
    z[0, 0] = -1.0  # callers get a copy; the cached result is unchanged
    assert est.estimate(img)[0, 0] > 0
    again = DepthAnythingV2Estimator(path=str(folder), device="cpu", input_size=56)
    assert again.model is est.model


def test_relative_checkpoint_is_refused(tmp_path):
    tiny_depth_anything(tmp_path, metric=False)
    with pytest.raises(ModelUnavailableError, match="RELATIVE depth"):
        DepthAnythingV2Estimator(path=str(tmp_path), device="cpu")
