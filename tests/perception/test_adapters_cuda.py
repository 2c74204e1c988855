"""The model adapters on a CUDA device, on the tiny random-weight models of test_adapters_common.

What a CPU machine cannot check: the tensors the adapters build reach the device and the model's
dtype (bfloat16, the 'auto' choice on CUDA, and float16), the outputs come back as the same numpy
types and shapes, and the continuous outputs agree with the same model on the CPU in float32.
Skipped where torch sees no CUDA device (CI and the 2-core development machine); run on a GPU
machine with ``pytest -m cuda tests/perception/test_adapters_cuda.py``.

``LOMANIP_TEST_TORCH_DEVICE=cpu`` runs the same checks on the CPU (a dry run of the test logic).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from lomanip_perception.adapters import _common as c
from lomanip_perception.datatypes import Detection, HumanPose2D3D

from .test_adapters_common import (noise_image, tiny_depth_anything, tiny_dinov2, tiny_florence2, tiny_flux,
                                   tiny_sam2, tiny_vitpose)  # fmt: skip

DEVICE = os.environ.get("LOMANIP_TEST_TORCH_DEVICE", "cuda")


def _device_available() -> bool:
    if DEVICE == "cpu":
        return True
    try:
        import torch
    except ImportError:
        return False
    return bool(torch.cuda.is_available())


pytestmark = [pytest.mark.cuda,
              pytest.mark.skipif(not _device_available(), reason=f"torch sees no {DEVICE} device")]  # fmt: skip

#: half-precision dtypes the adapters accept (bfloat16 is what 'auto' picks on CUDA)
HALF = ("bfloat16", "float16")


def _rel_err(a: np.ndarray, b: np.ndarray) -> float:
    """Median relative difference, for outputs of a random-weight model in another precision."""
    return float(np.median(np.abs(a - b) / np.maximum(np.abs(b), 1e-6)))


def test_auto_picks_the_device_and_bfloat16():
    import torch

    dev, dt = c.torch_setup("x", "detector", "auto", "auto")
    if DEVICE == "cuda":
        assert dev.type == "cuda" and dt == torch.bfloat16
    dev, dt = c.torch_setup("x", "detector", DEVICE, "float16")
    assert dev.type == DEVICE and dt == torch.float16


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    m = tmp_path_factory.mktemp
    return {"florence2": tiny_florence2(m("florence2")), "sam2": tiny_sam2(m("sam2")), "dinov2": tiny_dinov2(m("dinov2")),
            "depth": tiny_depth_anything(m("dav2")), "vitpose": tiny_vitpose(m("vitpose")), "flux": tiny_flux(m("flux"))}


@pytest.mark.parametrize("dtype", HALF)
def test_florence2_detects_on_the_device(folders, dtype):
    from lomanip_perception.adapters.florence2 import Florence2Detector

    det = Florence2Detector(path=str(folders["florence2"]), device=DEVICE, dtype=dtype, num_beams=2,
                            max_new_tokens=24)  # fmt: skip
    assert next(det.model.parameters()).device.type == DEVICE
    assert str(next(det.model.parameters()).dtype) == f"torch.{dtype}"
    img = noise_image(48, 80)
    text, score = det.answer(img, "Locate box in the image.")
    assert "<loc_" in text and 0.0 <= score <= 1.0
    for d in det.detect(img, ["box", "basket"]):
        assert isinstance(d, Detection) and d.label in ("box", "basket")
        x0, y0, x1, y1 = d.box
        assert 0 <= x0 < x1 <= 79 and 0 <= y0 < y1 <= 47
    assert DEVICE in det.description


@pytest.mark.parametrize("dtype", HALF)
def test_depth_anything_agrees_with_float32_on_the_cpu(folders, dtype):
    from lomanip_perception.adapters.depth_anything import DepthAnythingV2Estimator

    img = noise_image(60, 90)
    ref = DepthAnythingV2Estimator(path=str(folders["depth"]), device="cpu", dtype="float32", input_size=56).estimate(img)
    est = DepthAnythingV2Estimator(path=str(folders["depth"]), device=DEVICE, dtype=dtype, input_size=56)
    z = est.estimate(img)
    assert z.shape == (60, 90) and z.dtype == np.float32 and np.isfinite(z).all() and (z > 0).all()
    assert _rel_err(z, ref) < 0.05, _rel_err(z, ref)


def test_depth_anything_float32_on_the_device_matches_the_cpu(folders):
    from lomanip_perception.adapters.depth_anything import DepthAnythingV2Estimator

    img = noise_image(60, 90)
    ref = DepthAnythingV2Estimator(path=str(folders["depth"]), device="cpu", dtype="float32", input_size=56).estimate(img)
    z = DepthAnythingV2Estimator(path=str(folders["depth"]), device=DEVICE, dtype="float32", input_size=56).estimate(img)
    assert _rel_err(z, ref) < 5e-3, _rel_err(z, ref)  # TF32 convolutions on CUDA, not bit-equal


@pytest.mark.parametrize("dtype", HALF)
def test_dinov2_self_match_on_the_device(folders, dtype):
    from lomanip_perception.adapters.dinov2 import Dinov2Matcher

    m = Dinov2Matcher(path=str(folders["dinov2"]), device=DEVICE, dtype=dtype, input_size=56, stride_px=2,
                      nms_radius_px=4.0)  # fmt: skip
    a = noise_image(60, 90, 0)
    mask = np.zeros((60, 90), bool)
    mask[10:50, 15:70] = True
    q = np.array([[25, 15], [50, 30]])
    pool = m.match(a, mask, q, a, mask, 3)
    assert pool.candidates_uv.shape == (2, 3, 2) and pool.scores.shape == (2, 3)
    assert np.isfinite(pool.scores).all()
    assert np.abs(pool.candidates_uv[:, 0] - q).max() <= 2 and pool.scores[:, 0].min() > 0.9


@pytest.mark.parametrize("dtype", HALF)
def test_sam2_masks_on_the_device(folders, dtype):
    from lomanip_perception.adapters.sam2 import Sam2Segmenter

    img = noise_image(60, 90)
    dets = [Detection("box", (10.0, 10.0, 50.0, 40.0), 0.9), Detection("shelf", (0.0, 0.0, 89.0, 59.0), 0.5)]
    seg = Sam2Segmenter(path=str(folders["sam2"]), device=DEVICE, dtype=dtype)
    masks = seg.segment(img, dets)
    assert len(masks) == 2 and all(mk.shape == (60, 90) and mk.dtype == bool for mk in masks)
    v, u = np.nonzero(masks[0])
    if len(u):
        assert u.min() >= 5 and u.max() <= 55 and v.min() >= 5 and v.max() <= 45  # clipped to the box


def test_sam2_float32_on_the_device_matches_the_cpu(folders):
    from lomanip_perception.adapters.sam2 import Sam2Segmenter

    img = noise_image(60, 90)
    dets = [Detection("box", (10.0, 10.0, 50.0, 40.0), 0.9)]
    ref = Sam2Segmenter(path=str(folders["sam2"]), device="cpu", dtype="float32").segment(img, dets)[0]
    mk = Sam2Segmenter(path=str(folders["sam2"]), device=DEVICE, dtype="float32").segment(img, dets)[0]
    assert np.count_nonzero(mk != ref) <= 0.02 * mk.size  # pixels at the threshold may flip under TF32


@pytest.mark.parametrize("dtype", HALF)
def test_vitpose_lifts_a_pose_on_the_device(folders, dtype):
    from lomanip_perception import registry

    est = registry.build("pose_estimator", "vitpose", {
        "path": str(folders["vitpose"]), "device": DEVICE, "dtype": dtype, "min_confidence": 0.0,
        "depth": {"backend": "depth_anything_v2",
                  "params": {"path": str(folders["depth"]), "device": DEVICE, "dtype": dtype, "input_size": 56}}})
    pose = est.estimate(noise_image(96, 64))
    assert isinstance(pose, HumanPose2D3D)
    assert pose.uv.shape == (24, 2) and pose.xyz_camera.shape == (24, 3)
    assert np.isfinite(pose.uv).all() and np.isfinite(pose.xyz_camera).all()


@pytest.mark.parametrize("cpu_offload", [False, True])
def test_flux_generates_reproducibly_on_the_device(folders, cpu_offload):
    from lomanip_perception.adapters.flux import FluxGenerator
    from lomanip_perception.datatypes import GenerationRequest
    from lomanip_perception.prompts import generation_prompt, parse_subtask

    if cpu_offload and DEVICE == "cpu":
        pytest.skip("model CPU offload is a CUDA feature")
    gen = FluxGenerator(path=str(folders["flux"]), device=DEVICE, dtype="bfloat16", num_inference_steps=2, num_images=2,
                        max_sequence_length=16, cpu_offload=cpu_offload)  # fmt: skip
    st = parse_subtask(0, "pick up the box from the table", {"box", "table"})
    req = GenerationRequest(prompt=generation_prompt(st.prompt), seed=3, subtask=st, width=32, height=32)
    img = gen.generate(req)
    assert img.rgb.shape == (32, 32, 3) and img.rgb.dtype == np.uint8
    assert not np.array_equal(gen.last_candidates[0], gen.last_candidates[1])
    assert np.array_equal(gen.generate(req).rgb, img.rgb)  # seeded: the same image again
