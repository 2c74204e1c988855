"""Adapters' shared layer: offline weight resolution, fail-fast errors, lazy registration, and the
tiny random-weight model builders the per-adapter tests use (built from configs in code, saved with
save_pretrained to a tmp dir, loaded back through the adapters' real path; nothing downloaded)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lomanip_perception.adapters import _common as c
from lomanip_perception.errors import MODEL_UNAVAILABLE, ModelUnavailableError, PerceptionError

PKG = Path(__file__).resolve().parents[2] / "src" / "lomanip_perception"
PAPER_YAML = PKG / "config" / "paper_models.yaml"
OFFLINE_YAML = PKG / "config" / "perception.yaml"

# ---------------------------------------------------------------------------------- tiny builders

WORDS = ("locate in the image . a scene of person picking up box basket shelf table trolley has dark hair and is "
         "wearing casual clothes such shirt , jeans sneakers objects with category name").split()  # fmt: skip


def tiny_tokenizer(extra: tuple[str, ...] = (), max_length: int = 32):
    """A word-level fast tokenizer with Florence-2's special and location tokens."""
    from tokenizers import Tokenizer, models, pre_tokenizers
    from transformers import PreTrainedTokenizerFast

    special = ["<s>", "<pad>", "</s>", "<unk>"]
    vocab = {w: i for i, w in enumerate(dict.fromkeys(special + WORDS + list(extra)))}
    tk = Tokenizer(models.WordLevel(vocab, unk_token="<unk>"))
    tk.pre_tokenizer = pre_tokenizers.Whitespace()
    tk.add_special_tokens(special)
    tk.add_tokens([w for w in extra if w.startswith("<")])
    return PreTrainedTokenizerFast(tokenizer_object=tk, bos_token="<s>", eos_token="</s>", pad_token="<pad>",
                                   unk_token="<unk>", model_max_length=max_length)  # fmt: skip


def save_json(folder: Path, name: str, data: dict) -> None:
    (folder / name).write_text(json.dumps(data))


def tiny_florence2(folder: Path) -> Path:
    import torch
    from transformers import BartConfig, Florence2Config, Florence2ForConditionalGeneration, Florence2VisionConfig

    tok = tiny_tokenizer(tuple(f"<loc_{k}>" for k in range(1000)) + ("<poly>", "</poly>", "<image>"))
    V = len(tok)
    vc = Florence2VisionConfig(depths=(1, 1, 1, 1), embed_dim=(8, 16, 32, 64), num_heads=(1, 1, 2, 2),
                               num_groups=(1, 1, 2, 2), window_size=2, projection_dim=32, max_position_embeddings=16,
                               drop_path_rate=0.0)  # fmt: skip
    tc = BartConfig(vocab_size=V, d_model=32, encoder_layers=1, decoder_layers=1, encoder_attention_heads=2,
                    decoder_attention_heads=2, encoder_ffn_dim=64, decoder_ffn_dim=64, max_position_embeddings=128,
                    pad_token_id=1, bos_token_id=0, eos_token_id=2, decoder_start_token_id=2, forced_bos_token_id=0)
    cfg = Florence2Config(vision_config=vc.to_dict(), text_config=tc.to_dict(),
                          image_token_id=tok.convert_tokens_to_ids("<image>"))  # fmt: skip
    torch.manual_seed(0)
    Florence2ForConditionalGeneration(cfg).eval().save_pretrained(folder)
    tok.save_pretrained(folder)
    save_json(folder, "preprocessor_config.json", {"size": {"height": 64, "width": 64},
                                                   "image_mean": list(c.IMAGENET_MEAN), "image_std": list(c.IMAGENET_STD)})
    return folder


def tiny_sam2(folder: Path, size: int = 128) -> Path:
    import torch
    from transformers import (Sam2Config, Sam2HieraDetConfig, Sam2MaskDecoderConfig, Sam2Model,
                              Sam2PromptEncoderConfig, Sam2VisionConfig)  # fmt: skip

    S = size
    bb = Sam2HieraDetConfig(hidden_size=8, image_size=[S, S], blocks_per_stage=[1, 1, 2, 1],
                            embed_dim_per_stage=[8, 16, 32, 64], num_attention_heads_per_stage=[1, 1, 1, 1],
                            window_size_per_stage=[4, 4, 4, 2], global_attention_blocks=[3],
                            window_positional_embedding_background_size=[2, 2])  # fmt: skip
    vc = Sam2VisionConfig(backbone_config=bb.to_dict(), backbone_channel_list=[64, 32, 16, 8],
                          backbone_feature_sizes=[[S // 4] * 2, [S // 8] * 2, [S // 16] * 2], fpn_hidden_size=32)
    cfg = Sam2Config(vision_config=vc.to_dict(),
                     prompt_encoder_config=Sam2PromptEncoderConfig(hidden_size=32, image_size=S, patch_size=16).to_dict(),
                     mask_decoder_config=Sam2MaskDecoderConfig(hidden_size=32, mlp_dim=64, num_attention_heads=2,
                                                               iou_head_hidden_dim=32).to_dict())  # fmt: skip
    torch.manual_seed(0)
    Sam2Model(cfg).eval().save_pretrained(folder)
    return folder


def tiny_dinov2_config(**kw):
    from transformers import Dinov2Config

    return Dinov2Config(hidden_size=16, num_hidden_layers=2, num_attention_heads=2, intermediate_size=32,
                        patch_size=14, image_size=56, **kw)  # fmt: skip


def tiny_dinov2(folder: Path) -> Path:
    import torch
    from transformers import Dinov2Model

    torch.manual_seed(0)
    Dinov2Model(tiny_dinov2_config()).eval().save_pretrained(folder)
    return folder


def tiny_depth_anything(folder: Path, metric: bool = True) -> Path:
    import torch
    from transformers import DepthAnythingConfig, DepthAnythingForDepthEstimation

    bb = tiny_dinov2_config(out_features=["stage1", "stage2"], reshape_hidden_states=False)
    cfg = DepthAnythingConfig(backbone_config=bb.to_dict(), reassemble_hidden_size=16, neck_hidden_sizes=[8, 16],
                              reassemble_factors=[2, 1], fusion_hidden_size=16, head_hidden_size=8,
                              depth_estimation_type="metric" if metric else "relative", max_depth=20)  # fmt: skip
    torch.manual_seed(0)
    DepthAnythingForDepthEstimation(cfg).eval().save_pretrained(folder)
    return folder


def tiny_vitpose(folder: Path, num_labels: int = 17) -> Path:
    import torch
    from transformers import VitPoseBackboneConfig, VitPoseConfig, VitPoseForPoseEstimation

    bb = VitPoseBackboneConfig(image_size=[64, 48], patch_size=[16, 16], hidden_size=16, num_hidden_layers=1,
                               num_attention_heads=2, out_indices=[1])  # fmt: skip
    cfg = VitPoseConfig(backbone_config=bb.to_dict(), num_labels=num_labels)
    torch.manual_seed(0)
    VitPoseForPoseEstimation(cfg).eval().save_pretrained(folder)
    return folder


def tiny_flux(folder: Path) -> Path:
    import torch
    from diffusers import AutoencoderKL, FlowMatchEulerDiscreteScheduler, FluxPipeline, FluxTransformer2DModel
    from transformers import CLIPTextConfig, CLIPTextModel, T5Config, T5EncoderModel

    n = len(tiny_tokenizer())
    torch.manual_seed(0)
    tr = FluxTransformer2DModel(patch_size=1, in_channels=4, num_layers=1, num_single_layers=1, attention_head_dim=16,
                                num_attention_heads=2, joint_attention_dim=32, pooled_projection_dim=32,
                                axes_dims_rope=[4, 4, 8])  # fmt: skip
    clip = CLIPTextModel(CLIPTextConfig(bos_token_id=0, eos_token_id=2, pad_token_id=1, hidden_size=32,
                                        intermediate_size=37, num_attention_heads=4, num_hidden_layers=1,
                                        vocab_size=n, projection_dim=32, max_position_embeddings=32))  # fmt: skip
    t5 = T5EncoderModel(T5Config(vocab_size=n, d_model=32, d_kv=8, d_ff=37, num_layers=1, num_heads=4,
                                 pad_token_id=1, eos_token_id=2, decoder_start_token_id=1))  # fmt: skip
    vae = AutoencoderKL(sample_size=32, in_channels=3, out_channels=3, block_out_channels=(4,), layers_per_block=1,
                        latent_channels=1, norm_num_groups=1, use_quant_conv=False, use_post_quant_conv=False,
                        shift_factor=0.0609, scaling_factor=1.5035)  # fmt: skip
    FluxPipeline(scheduler=FlowMatchEulerDiscreteScheduler(), vae=vae, text_encoder=clip, tokenizer=tiny_tokenizer(),
                 text_encoder_2=t5, tokenizer_2=tiny_tokenizer(), transformer=tr).save_pretrained(folder)
    return folder


def noise_image(h: int, w: int, seed: int = 0):
    from lomanip_perception.datatypes import PerceptionImage

    return PerceptionImage(np.random.default_rng(seed).integers(0, 255, (h, w, 3), dtype=np.uint8))


# ---------------------------------------------------------------------------------- tests


@pytest.fixture()
def empty_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hub"))
    return tmp_path / "hub"


def test_missing_weights_give_one_line_naming_model_parameter_and_places(empty_cache, tmp_path):
    spec = c.WeightsSpec("Florence-2", "detector", str(tmp_path / "nope"), "florence-community/Florence-2-large")
    with pytest.raises(ModelUnavailableError) as e:
        c.resolve_weights(spec)
    msg = e.value.message
    assert e.value.code == MODEL_UNAVAILABLE and "\n" not in msg
    for part in ("Florence-2", "models.detector.params.path", str(tmp_path / "nope"), "no such folder",
                 str(empty_cache / "models--florence-community--Florence-2-large")):
        assert part in msg


def test_folder_without_config_is_not_accepted(empty_cache, tmp_path):
    (tmp_path / "half").mkdir()
    with pytest.raises(ModelUnavailableError, match="no config.json"):
        c.resolve_weights(c.WeightsSpec("SAM 2", "segmenter", str(tmp_path / "half")))


def test_weights_found_in_hf_cache_layout(empty_cache):
    snap = empty_cache / "models--org--tiny" / "snapshots" / "abc123"
    snap.mkdir(parents=True)
    (snap / "config.json").write_text("{}")
    (empty_cache / "models--org--tiny" / "refs").mkdir()
    (empty_cache / "models--org--tiny" / "refs" / "main").write_text("abc123")
    assert c.resolve_weights(c.WeightsSpec("Tiny", "matcher", "", "org/tiny")) == snap


def test_cuda_request_without_cuda_and_bad_dtype_are_clear():
    import torch

    if not torch.cuda.is_available():
        with pytest.raises(ModelUnavailableError, match="no CUDA device.*device: cpu"):
            c.torch_setup("X", "matcher", "cuda", "auto")
    with pytest.raises(PerceptionError, match="dtype must be"):
        c.torch_setup("X", "matcher", "cpu", "float8")
    dev, dt = c.torch_setup("X", "matcher", "cpu", "auto")
    assert dev.type == "cpu" and dt == torch.float32
    assert os.environ["HF_HUB_OFFLINE"] == "1"


def test_corrupt_weights_become_one_line(tmp_path):
    (tmp_path / "config.json").write_text("{not json")
    from lomanip_perception.adapters.sam2 import Sam2Segmenter

    with pytest.raises(ModelUnavailableError) as e:
        Sam2Segmenter(path=str(tmp_path), device="cpu")
    assert "cannot load the weights" in e.value.message and "\n" not in e.value.message


def test_unavailable_paper_models_name_the_alternative():
    from lomanip_perception import registry

    for role, name, alt in (("pose_estimator", "wham", "vitpose"), ("depth_estimator", "metric3d", "depth_anything_v2")):
        assert name in registry.backends(role)
        with pytest.raises(ModelUnavailableError, match=alt):
            registry.build(role, name, {})


def _run(code: str, env_extra: dict) -> subprocess.CompletedProcess:
    env = {**os.environ, **env_extra}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)


def test_paper_model_file_without_weights_fails_fast_with_one_line(tmp_path):
    """The paper's parameter file on a machine without the weights: MODEL_UNAVAILABLE naming the
    first model (FLUX.1), no traceback, no torch import, no network."""
    code = f"""
import sys, time
t = time.perf_counter()
from lomanip_perception.config import load_config, build_from_config
from lomanip_perception.errors import ModelUnavailableError
try:
    build_from_config(load_config({str(PAPER_YAML)!r}))
except ModelUnavailableError as e:
    print("ERR", e.code, e.message)
print("SECONDS", time.perf_counter() - t)
print("HEAVY", sorted(m for m in ("torch", "transformers", "diffusers") if m in sys.modules))
"""
    r = _run(code, {"HF_HUB_CACHE": str(tmp_path / "hub"), "HF_HUB_OFFLINE": "0"})
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.strip().splitlines())
    assert lines["ERR"].startswith("MODEL_UNAVAILABLE FLUX.1 (image_generator): weights not found")
    assert "models.image_generator.params.path" in lines["ERR"] and "never downloads" in lines["ERR"]
    assert lines["HEAVY"] == "[]"  # failed before importing any deep-learning library
    assert "Traceback" not in r.stderr


def test_offline_default_imports_nothing_heavy():
    code = """
import sys, time
t = time.perf_counter()
from lomanip_perception.config import load_config, build_from_config
models, transfer, seed = build_from_config(load_config())
print(sorted(set(models.names().values())))
print(sorted(m for m in ("torch", "transformers", "diffusers", "huggingface_hub") if m in sys.modules))
"""
    r = _run(code, {})
    assert r.returncode == 0, r.stderr
    names, heavy = r.stdout.strip().splitlines()[-2:]
    assert names == "['synthetic']"
    assert heavy == "[]"


def test_every_adapter_is_registered_lazily():
    from lomanip_perception import registry

    expected = {"image_generator": "flux", "detector": "florence2", "segmenter": "sam2",
                "depth_estimator": "depth_anything_v2", "matcher": "dinov2", "pose_estimator": "vitpose"}
    for role, name in expected.items():
        assert name in registry.backends(role)
    assert "geoaware_sc" in registry.backends("matcher")


def test_every_adapter_without_weights_raises_model_unavailable(empty_cache):
    from lomanip_perception import registry

    for role, name in (("detector", "florence2"), ("segmenter", "sam2"), ("matcher", "dinov2"),
                       ("matcher", "geoaware_sc"), ("depth_estimator", "depth_anything_v2"),
                       ("image_generator", "flux"), ("pose_estimator", "vitpose")):
        with pytest.raises(ModelUnavailableError, match=f"models.{role}.params.path"):
            registry.build(role, name, {"path": ""})
