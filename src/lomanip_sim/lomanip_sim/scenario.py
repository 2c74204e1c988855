"""Scenario parameters (paper Sec. V): S1 basket retrieval and S2 trolley.

Why: scenario parameters are inputs, not constants. Defaults and the paper's test grids live in
``config/scenarios.yaml``; :func:`load_scenario` merges user overrides onto the defaults and
validates every value, raising :class:`ScenarioError` with a one-line message a user can act on
(unknown scenario, unknown key, wrong type, non-positive mass or size, malformed YAML).

Conventions: metres, kilograms, radians; sizes are FULL extents (world.py halves them for MuJoCo);
positions are (x, y) footprint centres in the world frame; the G1 starts at the origin facing +x.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import sys
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Mapping

import yaml

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


class ScenarioError(ValueError):
    """Invalid scenario name, parameter or scenario file (message is one line)."""


@dataclass(frozen=True)
class CommonParams:
    """Parameters every scenario has: physics, robot start, scene camera."""

    name: ClassVar[str] = ""
    timestep: float = 0.002
    #: MuJoCo's noslip post-solve (iterations; 0 = off). Why: MuJoCo's soft friction lets a contact
    #: slip at a speed proportional to its load even inside the friction cone; a grasping hand crept
    #: up S1's box at 5-6 cm/s. With 10 S1's plans get further (the fixture's plan falls at 6.4 s,
    #: not 5.1), S2's nominal plan still executes to task success, and so do three push plans of
    #: tools/bench_push.py; with 30 S2 nominal fell (docs/execution.md, sessions 37-38)
    noslip_iterations: int = 10
    #: MuJoCo's friction: its ratio of frictional to normal constraint impedance and its cone
    #: ("pyramidal" or "elliptic"). Why not MuJoCo's defaults (1, pyramidal): with those the friction
    #: is as soft as the normal contact, and a loaded contact creeps while inside its cone. S1's stance
    #: sole, loaded on its two heel spheres, spun about the leg's hip-yaw axis at up to 1.2 rad/s (a
    #: heel sphere sliding at 56 mm/s under 39 % of its friction limit; noslip does not change it);
    #: impratio 10 cut that to 0.3 rad/s, with the elliptic cone 0.03 (1-5 mm/s), as MuJoCo's
    #: documentation advises (harder friction, elliptic cones). The small cases and the demo's push
    #: plans execute as before (docs/execution.md, sessions 45-46)
    impratio: float = 10.0
    friction_cone: str = "elliptic"
    floor_friction: float = 1.0
    robot_position: Vec2 = (0.0, 0.0)
    robot_yaw: float = 0.0
    camera_width: int = 640
    camera_height: int = 480
    camera_fovy: float = 60.0
    camera_position: Vec3 = (3.5, -2.0, 2.2)
    camera_target: Vec3 = (0.8, 0.3, 0.7)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (lists for vectors) with the scenario name under 'scenario'."""
        d: dict[str, Any] = {"scenario": self.name}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            d[f.name] = list(v) if isinstance(v, tuple) else v
        return d

    def to_yaml(self) -> str:
        """Flat YAML of the parameters (for the SceneObjects.parameters_yaml field)."""
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)

    def replace(self, **overrides: Any):
        """Validated copy with some parameters changed."""
        return _build(type(self), {**self.to_dict(), **overrides}, source="overrides")


@dataclass(frozen=True)
class S1BasketParams(CommonParams):
    """S1 basket retrieval: box on the floor, shelf, basket on the shelf top."""

    name: ClassVar[str] = "s1_basket"
    box_mass: float = 2.5
    box_yaw: float = 0.0
    box_size: Vec3 = (0.40, 0.40, 0.30)
    box_position: Vec2 = (0.70, 0.0)
    box_friction: float = 0.8
    shelf_size: Vec3 = (0.40, 0.80, 1.50)
    shelf_position: Vec2 = (1.90, 1.00)
    shelf_yaw: float = 0.0
    basket_mass: float = 0.5
    basket_size: Vec3 = (0.30, 0.40, 0.25)
    basket_setback: float = 0.03
    basket_wall: float = 0.01
    camera_position: Vec3 = (3.0, -1.7, 2.0)
    camera_target: Vec3 = (1.0, 0.5, 0.8)


@dataclass(frozen=True)
class S2TrolleyParams(CommonParams):
    """S2 trolley: box on a table, trolley with hinged rear wheels and front casters."""

    name: ClassVar[str] = "s2_trolley"
    box_mass: float = 2.5
    box_yaw: float = 0.0
    box_size: Vec3 = (0.30, 0.30, 0.25)
    box_offset: Vec2 = (0.0, 0.0)
    box_friction: float = 0.8
    table_size: Vec3 = (0.60, 0.80, 0.70)
    table_position: Vec2 = (0.75, 0.0)
    table_yaw: float = 0.0
    trolley_mass: float = 8.0
    trolley_size: Vec3 = (0.80, 0.50, 0.35)
    trolley_position: Vec2 = (0.20, -1.10)
    trolley_yaw: float = 0.0
    trolley_handle_height: float = 0.85
    wheel_radius: float = 0.06
    wheel_mass: float = 0.3
    #: rolling resistance per wheel (N): the wheel hinge's frictionloss is this x wheel_radius. The
    #: TO allows the same longitudinal force per support corner (lomanip_to.discretize), so the trolley
    #: it plans can be brought to rest by its wheels: the hands only push (a friction contact on the
    #: handle), and a free-rolling trolley could only be stopped by pulling
    wheel_rolling_resistance: float = 1.5
    caster_trail: float = 0.04
    camera_position: Vec3 = (2.9, 1.7, 1.9)
    camera_target: Vec3 = (0.7, -0.5, 0.6)


ScenarioParams = S1BasketParams | S2TrolleyParams
SCENARIOS: dict[str, type[CommonParams]] = {S1BasketParams.name: S1BasketParams, S2TrolleyParams.name: S2TrolleyParams}

FRICTION_CONES = ("pyramidal", "elliptic")  # CommonParams.friction_cone, in MuJoCo's mjtCone order

# Keys that must be > 0 (masses, sizes, ...) and >= 0 (frictions, offsets).
_POSITIVE_SUFFIXES = ("_mass", "_size", "timestep", "camera_width", "camera_height", "camera_fovy", "_radius",
                      "_wall", "_handle_height", "impratio")  # fmt: skip
_NON_NEGATIVE_SUFFIXES = ("_friction", "_setback", "_trail", "_resistance", "_iterations")


def default_scenarios_path() -> Path:
    """Where scenarios.yaml is found: $LOMANIP_SCENARIOS_FILE, the source tree, or <prefix>/share."""
    env = os.environ.get("LOMANIP_SCENARIOS_FILE")
    if env:
        return Path(env)
    candidates = [
        Path(__file__).resolve().parent.parent / "config" / "scenarios.yaml",
        Path(sys.prefix) / "share" / "lomanip_sim" / "config" / "scenarios.yaml",
    ]
    for c in candidates:
        if c.is_file():
            return c
    return candidates[0]


def _read_file(path: Path) -> dict[str, Any]:
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ScenarioError(f"cannot read scenario file {path}: {e.strerror}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else "unknown line"
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ScenarioError(f"malformed YAML in {path} at {where}: {problem}") from None
    if not isinstance(data, dict) or not isinstance(data.get("scenarios"), dict):
        raise ScenarioError(f"scenario file {path} has no 'scenarios' mapping at the top level")
    return data


def _entry(data: dict[str, Any], name: str, path: Path) -> dict[str, Any]:
    if not isinstance(name, str) or name not in SCENARIOS:
        raise ScenarioError(f"unknown scenario {name!r}; valid scenarios: {', '.join(SCENARIOS)}")
    entry = data["scenarios"].get(name)
    if not isinstance(entry, dict):
        raise ScenarioError(f"scenario {name!r} is missing from {path}")
    return entry


def _convert(key: str, value: Any, typ: Any, scenario: str) -> Any:
    """Check/convert one value to the dataclass field type (bools are not numbers)."""
    def bad(expected: str) -> ScenarioError:
        return ScenarioError(f"scenario {scenario}: parameter {key!r} must be {expected}, got {value!r}")

    if typ is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise bad("a finite number")
        return float(value)
    if typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise bad("an integer")
        return value
    if typ is str:
        if not isinstance(value, str):
            raise bad("a string")
        return value
    if typing.get_origin(typ) is tuple:
        n = len(typing.get_args(typ))
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise bad(f"a list of {n} numbers")
        return tuple(_convert(key, v, float, scenario) for v in value)
    return value


def _build(cls: type[CommonParams], values: Mapping[str, Any], source: str) -> CommonParams:
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs: dict[str, Any] = {}
    for key, value in values.items():
        if key == "scenario":
            if value not in (None, cls.name):
                raise ScenarioError(f"parameters say scenario {value!r} but {cls.name!r} was requested")
            continue
        if key not in names:
            raise ScenarioError(f"unknown parameter {key!r} in {source} for scenario {cls.name}; valid: {', '.join(names)}")
        v = _convert(key, value, hints[key], cls.name)
        vals = v if isinstance(v, tuple) else (v,)
        if key.endswith(_POSITIVE_SUFFIXES) and any(x <= 0 for x in vals):
            raise ScenarioError(f"scenario {cls.name}: parameter {key!r} must be > 0, got {value!r}")
        if key.endswith(_NON_NEGATIVE_SUFFIXES) and any(x < 0 for x in vals):
            raise ScenarioError(f"scenario {cls.name}: parameter {key!r} must be >= 0, got {value!r}")
        kwargs[key] = v
    params = cls(**kwargs)
    if params.friction_cone not in FRICTION_CONES:
        raise ScenarioError(f"scenario {cls.name}: friction_cone must be one of {', '.join(FRICTION_CONES)}, "
                            f"got {params.friction_cone!r}")
    if params.camera_fovy >= 180.0:
        raise ScenarioError(f"scenario {cls.name}: camera_fovy must be < 180 deg, got {params.camera_fovy}")
    return params


def scenario_names() -> list[str]:
    """Valid scenario names."""
    return list(SCENARIOS)


def load_scenario(name: str, overrides: Mapping[str, Any] | None = None, path: str | Path | None = None) -> ScenarioParams:
    """Defaults of scenario ``name`` from the YAML file, with ``overrides`` applied and validated."""
    p = Path(path) if path is not None else default_scenarios_path()
    data = _read_file(p)
    entry = _entry(data, name, p)
    base = entry.get("parameters") or {}
    if not isinstance(base, dict):
        raise ScenarioError(f"scenario {name!r} in {p}: 'parameters' must be a mapping")
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ScenarioError(f"overrides must be a mapping of parameter names to values, got {type(overrides).__name__}")
    cls = SCENARIOS[name]
    _build(cls, base, source=str(p))  # report file errors as file errors
    return _build(cls, {**base, **dict(overrides or {})}, source="overrides")  # type: ignore[return-value]


def load_grid(name: str, path: str | Path | None = None) -> list[ScenarioParams]:
    """The paper's test grid of scenario ``name`` (cartesian product of the 'grid' lists)."""
    p = Path(path) if path is not None else default_scenarios_path()
    data = _read_file(p)
    grid = _entry(data, name, p).get("grid") or {}
    if not isinstance(grid, dict) or not all(isinstance(v, list) and v for v in grid.values()):
        raise ScenarioError(f"scenario {name!r} in {p}: 'grid' must map parameter names to non-empty lists")
    keys = list(grid)
    return [load_scenario(name, dict(zip(keys, combo)), p) for combo in itertools.product(*(grid[k] for k in keys))]


def parse_overrides_yaml(text: str) -> dict[str, Any]:
    """Parse a flat YAML mapping such as ``"{box_mass: 5.0, box_yaw: 0.6}"`` (empty -> {})."""
    if not text or not text.strip():
        return {}
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ScenarioError(f"malformed overrides YAML{where}: {getattr(e, 'problem', None) or e}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ScenarioError(f"overrides must be a YAML mapping, got {type(data).__name__}")
    return data


# Convenience for callers that need a field list (e.g. ROS parameter declarations).
def parameter_names(name: str) -> list[str]:
    """Parameter names of scenario ``name``."""
    if name not in SCENARIOS:
        raise ScenarioError(f"unknown scenario {name!r}; valid scenarios: {', '.join(SCENARIOS)}")
    return [f.name for f in dataclasses.fields(SCENARIOS[name])]


__all__ = [
    "CommonParams", "S1BasketParams", "S2TrolleyParams", "ScenarioParams", "ScenarioError", "SCENARIOS",
    "load_scenario", "load_grid", "scenario_names", "parameter_names", "parse_overrides_yaml",
    "default_scenarios_path",
]  # fmt: skip
