"""DINOv2 matcher: top-N pools inside the target mask, distinct candidates, self-match recovers the
query, on a tiny random-weight Dinov2Model."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.adapters.dinov2 import Dinov2Matcher
from lomanip_perception.errors import PerceptionError

from .test_adapters_common import noise_image, tiny_dinov2


@pytest.fixture(scope="module")
def matcher(tmp_path_factory):
    return Dinov2Matcher(path=str(tiny_dinov2(tmp_path_factory.mktemp("dinov2"))), device="cpu", input_size=56,
                         stride_px=2, nms_radius_px=4.0)


def _masks():
    ma = np.zeros((60, 90), bool)
    ma[10:40, 20:60] = True
    mb = np.zeros((70, 80), bool)
    mb[20:60, 10:50] = True
    return ma, mb


def test_pool_shape_inside_mask_sorted_and_distinct(matcher):
    a, b = noise_image(60, 90, 0), noise_image(70, 80, 1)
    ma, mb = _masks()
    q = np.array([[25, 15], [50, 30], [30, 35]])
    pool = matcher.match(a, ma, q, b, mb, 5)
    assert pool.candidates_uv.shape == (3, 5, 2) and pool.scores.shape == (3, 5)
    assert (pool.query_uv == q).all()
    assert mb[pool.candidates_uv[..., 1], pool.candidates_uv[..., 0]].all()
    assert (np.diff(pool.scores, axis=1) <= 1e-9).all() and ((pool.scores >= 0) & (pool.scores <= 1)).all()
    d = np.linalg.norm(pool.candidates_uv[:, :, None] - pool.candidates_uv[:, None, :], axis=-1)
    assert (d[:, ~np.eye(5, dtype=bool)] >= 4.0).all()  # the pool holds distinct places


def test_self_match_finds_the_query(matcher):
    a = noise_image(60, 90, 0)
    ma, _ = _masks()
    q = np.array([[25, 15], [50, 30]])
    pool = matcher.match(a, ma, q, a, ma, 3)
    assert np.abs(pool.candidates_uv[:, 0] - q).max() <= 2
    assert pool.scores[:, 0].min() > 0.95


def test_empty_mask_is_a_clear_error(matcher):
    a = noise_image(20, 20)
    m = np.zeros((20, 20), bool)
    with pytest.raises(PerceptionError, match="mask is empty"):
        matcher.match(a, m, np.array([[1, 1]]), a, m, 3)
