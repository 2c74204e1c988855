"""FLUX adapter: the paper's prompt through a tiny random-weight FluxPipeline (diffusers), seeded
candidates, the selection rules, resolution checks."""
from __future__ import annotations

import numpy as np
import pytest

from lomanip_perception.adapters.flux import FluxGenerator
from lomanip_perception.datatypes import Detection, GenerationRequest
from lomanip_perception.errors import PerceptionError
from lomanip_perception.prompts import generation_prompt, parse_subtask

from .test_adapters_common import tiny_flux


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tiny_flux(tmp_path_factory.mktemp("flux"))


def _request(seed=3, w=32, h=32):
    st = parse_subtask(0, "pick up the box from the table", {"box", "table"})
    return GenerationRequest(generation_prompt(st.prompt), seed, st, w, h)


def test_seeded_candidates_and_first_selection(folder):
    gen = FluxGenerator(path=str(folder), device="cpu", num_inference_steps=2, num_images=3, max_sequence_length=16)
    img = gen.generate(_request())
    assert img.rgb.shape == (32, 32, 3) and img.rgb.dtype == np.uint8 and img.depth is None
    assert gen.last_selected == 0 and len(gen.last_candidates) == 3
    assert not np.array_equal(gen.last_candidates[0], gen.last_candidates[1])  # a different seed per image
    again = gen.generate(_request())
    assert np.array_equal(again.rgb, img.rgb)  # reproducible
    assert "seed 3000" in img.source
    with pytest.raises(PerceptionError, match="multiples of 2"):  # tiny VAE: scale factor 1
        gen.generate(_request(w=33))
    with pytest.raises(PerceptionError, match="empty prompt"):
        gen.generate(GenerationRequest("  ", 0, None, 32, 32))


class _Picky:
    """Test double of a detector: finds the person and the box only in candidate 1."""

    name = "test-double"

    def __init__(self):
        self.calls = 0

    def detect(self, image, labels):
        k, self.calls = self.calls, self.calls + 1
        assert labels == ["person", "box", "table"]
        return [Detection("person", (0, 0, 5, 5), 0.8), Detection("box", (0, 0, 5, 5), 0.7)] if k == 1 else []


def test_detector_selection_keeps_the_image_showing_person_and_objects(folder):
    gen = FluxGenerator(path=str(folder), device="cpu", num_inference_steps=1, num_images=3, max_sequence_length=16,
                        selection="detector", detector=_Picky())  # fmt: skip
    img = gen.generate(_request(seed=1))
    assert gen.last_selected == 1 and np.array_equal(img.rgb, gen.last_candidates[1])
    assert "image 1 of 3" in img.source


def test_bad_parameters(folder):
    with pytest.raises(ValueError, match="selection"):
        FluxGenerator(path=str(folder), selection="best")
    with pytest.raises(PerceptionError, match="params.detector"):
        FluxGenerator(path=str(folder), device="cpu", selection="detector")
