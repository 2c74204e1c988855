"""Registry of model backends per role, selected by name from YAML / ROS parameters.

A configuration is a mapping ``{role: {"backend": name, "params": {...}}}`` (see
config/perception.yaml). ``build_models(config)`` returns a :class:`ModelSet`. The names of the
paper's models are served by lomanip_perception.adapters (registered lazily: no torch import until a
backend is built); one without weights on disk, or without an adapter, fails with MODEL_UNAVAILABLE
and one line saying why, instead of a crash.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

from .errors import ModelUnavailableError, PerceptionError, INVALID_REQUEST
from .roles import ROLES

Factory = Callable[..., Any]
_REGISTRY: dict[str, dict[str, Factory]] = {r: {} for r in ROLES}

#: the paper's model per role, for messages and placeholders
PAPER_MODELS = {"image_generator": "flux", "detector": "florence2", "segmenter": "sam2",
                "depth_estimator": "metric3d", "matcher": "geoaware_sc", "pose_estimator": "wham"}


def register(role: str, name: str) -> Callable[[Factory], Factory]:
    if role not in _REGISTRY:
        raise ValueError(f"unknown role {role!r}; roles: {', '.join(ROLES)}")

    def deco(factory: Factory) -> Factory:
        _REGISTRY[role][name] = factory
        return factory

    return deco


def backends(role: str) -> list[str]:
    _ensure_builtin()
    return sorted(_REGISTRY[role])


def build(role: str, name: str, params: Mapping[str, Any] | None = None) -> Any:
    _ensure_builtin()
    if role not in _REGISTRY:
        raise PerceptionError(INVALID_REQUEST, f"unknown model role {role!r}; roles: {', '.join(ROLES)}")
    try:
        factory = _REGISTRY[role][name]
    except KeyError:
        raise PerceptionError(INVALID_REQUEST, f"unknown {role} backend {name!r}; available: "
                              f"{', '.join(sorted(_REGISTRY[role]))}") from None  # fmt: skip
    try:
        return factory(**dict(params or {}))
    except TypeError as exc:
        raise PerceptionError(INVALID_REQUEST, f"bad parameters for {role} backend {name!r}: {exc}") from exc


@dataclass
class ModelSet:
    image_generator: Any
    detector: Any
    segmenter: Any
    depth_estimator: Any
    matcher: Any
    pose_estimator: Any

    def names(self) -> dict[str, str]:
        return {r: getattr(getattr(self, r), "name", type(getattr(self, r)).__name__) for r in ROLES}

    def describe(self) -> dict[str, str]:
        """Backend per role with what serves it (model, folder, device, dtype) where an adapter says."""
        return {r: getattr(getattr(self, r), "description", None) or self.names()[r] for r in ROLES}


def build_models(config: Mapping[str, Any]) -> ModelSet:
    """Build every role from ``{role: {"backend": ..., "params": {...}}}``; missing roles default
    to the synthetic backend."""
    built = {}
    for role in ROLES:
        entry = dict(config.get(role) or {})
        built[role] = build(role, entry.get("backend", "synthetic"), entry.get("params") or {})
    return ModelSet(**built)


def _placeholder(role: str, name: str) -> Factory:
    def factory(**params):
        raise ModelUnavailableError(
            f"{role} backend {name!r} (the paper's model) has no adapter in this build and its weights cannot "
            f"be downloaded on this machine; use backend 'synthetic' (offline stand-in) or install an adapter "
            f"that loads {name} from a local path")
    return factory


_BUILTIN_DONE = False


def _ensure_builtin() -> None:
    global _BUILTIN_DONE
    if _BUILTIN_DONE:
        return
    _BUILTIN_DONE = True
    from .synthetic import standins  # noqa: F401  (registers the 'synthetic' backends)
    from .synthetic import generator  # noqa: F401
    from .adapters import register_adapters  # lazy: imports no torch until a backend is built

    register_adapters(_REGISTRY)
    for role, name in PAPER_MODELS.items():
        _REGISTRY[role].setdefault(name, _placeholder(role, name))
