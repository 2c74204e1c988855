"""Perception config: the package YAML, overrides, and clear errors for bad files."""
from __future__ import annotations

import pytest

from lomanip_perception.config import build_from_config, default_config_path, load_config
from lomanip_perception.errors import INVALID_REQUEST, PerceptionError


def test_default_config_builds_synthetic_models_and_paper_transfer_settings():
    assert default_config_path().exists()
    cfg = load_config()
    models, transfer, seed = build_from_config(cfg)
    assert set(models.names().values()) == {"synthetic"}
    assert transfer.method == "geometry_aware" and transfer.iterations == 10 and seed == 0
    assert cfg["models"]["image_generator"]["params"]["width"] == 1024


def test_overrides_merge_deeply():
    cfg = load_config(overrides={"models": {"matcher": {"params": {"outlier_rate": 0.1}}},
                                 "transfer": {"method": "geometry_unaware"}})
    assert cfg["models"]["matcher"]["params"]["outlier_rate"] == 0.1
    assert cfg["models"]["matcher"]["params"]["flip_fraction"] == 0.5  # kept from the file
    models, transfer, _ = build_from_config(cfg)
    assert transfer.method == "geometry_unaware" and models.matcher.outlier_rate == 0.1


def test_bad_files_and_settings(tmp_path):
    with pytest.raises(PerceptionError) as e:
        load_config(tmp_path / "missing.yaml")
    assert e.value.code == INVALID_REQUEST
    bad = tmp_path / "bad.yaml"
    bad.write_text("- a list\n")
    with pytest.raises(PerceptionError):
        load_config(bad)
    bad.write_text("models: {matcher: [unclosed\n")
    with pytest.raises(PerceptionError):
        load_config(bad)
    with pytest.raises(PerceptionError) as e:
        build_from_config({"transfer": {"method": "telepathy"}})
    assert e.value.code == INVALID_REQUEST and "telepathy" in e.value.message
    with pytest.raises(PerceptionError):
        build_from_config({"transfer": {"no_such_key": 1}})
