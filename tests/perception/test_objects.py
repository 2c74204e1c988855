"""Parametric instances of the scene classes."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.synthetic import objects as objs


@pytest.mark.parametrize("cls", objs.CLASSES)
def test_bounding_box_matches_the_requested_size(cls):
    size = np.array(objs.NOMINAL_SIZES[cls]) * 1.1
    o = objs.make_object(cls, cls, size, (0.5, 0.2, 0.2, 1.0), (0, 0, 0), 0.3)
    c, h = o.bbox_local()
    assert np.allclose(2 * h, size, atol=0.01)
    lo = c[2] - h[2]
    assert abs(lo + objs.bottom_offset(cls, size)) < 0.01  # origin height above the lowest point
    assert 0 < objs.top_height_local(o) <= c[2] + h[2] + 1e-9


def test_unknown_class_and_palette():
    with pytest.raises(ValueError):
        objs.build_primitives("sofa", (1, 1, 1), (1, 1, 1, 1))
    rng = np.random.default_rng(0)
    a = objs.palette(rng)
    b = objs.palette(rng, avoid=a)
    assert len(a) == 4 and np.linalg.norm(np.subtract(a[:3], b[:3])) > 0.25
