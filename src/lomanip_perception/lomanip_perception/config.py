"""Perception configuration: YAML file (config/perception.yaml) + overrides -> models and transfer."""
from __future__ import annotations

import copy
import sys
from pathlib import Path
from typing import Any

import yaml

from .errors import INVALID_REQUEST, PerceptionError
from .registry import ModelSet, build_models
from .transfer import TransferConfig


def default_config_path() -> Path:
    here = Path(__file__).resolve().parent.parent / "config" / "perception.yaml"
    if here.exists():
        return here
    return Path(sys.prefix) / "share" / "lomanip_perception" / "config" / "perception.yaml"


def _merge(a: dict, b: dict) -> dict:
    out = copy.deepcopy(a)
    for k, v in (b or {}).items():
        out[k] = _merge(out.get(k) or {}, v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def load_config(path: str | Path | None = None, overrides: dict | None = None) -> dict[str, Any]:
    p = Path(path) if path else default_config_path()
    try:
        data = yaml.safe_load(p.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise PerceptionError(INVALID_REQUEST, f"cannot read perception config {p}: {exc}") from exc
    if not isinstance(data, dict):
        raise PerceptionError(INVALID_REQUEST, f"perception config {p} is not a mapping")
    return _merge(data, overrides or {})


def build_from_config(cfg: dict) -> tuple[ModelSet, TransferConfig, int]:
    try:
        transfer = TransferConfig(**(cfg.get("transfer") or {}))
    except (TypeError, ValueError) as exc:
        raise PerceptionError(INVALID_REQUEST, f"bad transfer settings: {exc}") from exc
    return build_models(cfg.get("models") or {}), transfer, int(cfg.get("seed", 0))
