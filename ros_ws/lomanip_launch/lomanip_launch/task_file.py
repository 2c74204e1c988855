"""Task files for `lomanip plan`: a scenario, its prompt list and optional placement goals, in YAML.

    scenario: s1_basket                  # s1_basket | s2_trolley
    scenario_overrides: {box_mass: 2.5}  # optional, as `--set`
    prompts: ["pick up the box", ...]
    placement_goals:                     # optional
      - {object: box, position: [1.0, 0.4, 0.15], yaw: 0.0}
    options: {max_iterations: 500}       # optional lomanip_msgs/TrajectoryOptions fields;
                                         # subtask_options as {subtask index: {option: value}};
                                         # solver_options as a mapping {ipopt name: value}
                                         # (YAML's yes/no booleans are ipopt's "yes"/"no");
                                         # weights as a mapping {TO cost weight name: number}

No rclpy here: the file is validated into a plain :class:`Task`; ``plan_client`` turns it into a goal.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from lomanip_launch.environment import config_dir

TASKS_DIR = config_dir() / "tasks"
_OPTION_FIELDS = {"use_keyframe_base_cost": bool, "use_keyframe_foot_cost": bool, "use_keyframe_warm_start": bool,
                  "collision_hard_constraint": bool, "collision_penalty": bool, "collision_homotopy": bool,
                  "max_iterations": int, "output_rate": float, "time_limit": float, "inertial_torque_groups": list,
                  "single_support_com_lateral": float, "waist_yaw_range": float,
                  "interval_momentum_tolerance": float, "upper_body_acceleration_limit": float,
                  "upper_body_speed_limit": float,
                  "carried_object_clearance": float, "body_object_clearance": float, "hand_object_clearance": float, "dt_lift": float, "dt_reach": float, "carry_reach": float,
                  "placement_tolerance": float, "lift_with_previous_segment": bool, "segment_moving_objects": bool,
                  "load_in_double_support_margin": bool, "resting_object_dynamics": bool, "cop_margin_front": float,
                  "cop_margin_side": float,
                  "hand_standoff": float, "forearm_clear_of_held_object": bool,
                  "final_warm_start_max_violation": float, "final_cold_retry": bool, "hold_placement_goals": bool,
                  "collision_screen_distance": float, "solver_options": dict, "weights": dict,
                  "subtask_options": dict}


class TaskFileError(ValueError):
    """A task file that cannot be used; the message names the file and the field."""


@dataclass
class Placement:
    object_id: str
    position: tuple[float, float, float]
    yaw: float


@dataclass
class Task:
    scenario: str
    prompts: list[str]
    scenario_overrides: dict = field(default_factory=dict)
    placement_goals: list[Placement] = field(default_factory=list)
    options: dict = field(default_factory=dict)


def task_path(name_or_path: str) -> Path:
    """A path as given, or the name of a task shipped in ros_ws/config/tasks (``s1_basket``)."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return path
    return TASKS_DIR / f"{name_or_path}.yaml"


def load_task(name_or_path: str) -> Task:
    path = task_path(name_or_path)
    if not path.is_file():
        shipped = ", ".join(sorted(p.stem for p in TASKS_DIR.glob("*.yaml")))
        raise TaskFileError(f"task file {path} does not exist (shipped tasks: {shipped})")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise TaskFileError(f"task file {path} is not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise TaskFileError(f"task file {path} must be a mapping with 'scenario' and 'prompts'")
    return task_from_dict(data, str(path))


def task_from_dict(data: dict, where: str = "task") -> Task:
    unknown = set(data) - {"scenario", "scenario_overrides", "prompts", "placement_goals", "options", "description"}
    if unknown:
        raise TaskFileError(f"{where}: unknown field(s) {', '.join(sorted(unknown))}")
    scenario = data.get("scenario")
    if not isinstance(scenario, str) or not scenario:
        raise TaskFileError(f"{where}: 'scenario' must be a scenario name such as s1_basket")
    prompts = data.get("prompts")
    if not isinstance(prompts, list) or not prompts or not all(isinstance(p, str) and p.strip() for p in prompts):
        raise TaskFileError(f"{where}: 'prompts' must be a non-empty list of non-empty strings")
    overrides = data.get("scenario_overrides") or {}
    if not isinstance(overrides, dict):
        raise TaskFileError(f"{where}: 'scenario_overrides' must be a mapping")
    goals = [_placement(g, f"{where}: placement_goals[{i}]") for i, g in enumerate(data.get("placement_goals") or [])]
    options = data.get("options") or {}
    if not isinstance(options, dict):
        raise TaskFileError(f"{where}: 'options' must be a mapping")
    for key, value in options.items():
        if key not in _OPTION_FIELDS:
            raise TaskFileError(f"{where}: unknown option {key!r}; options: {', '.join(_OPTION_FIELDS)}")
        if not isinstance(value, _OPTION_FIELDS[key]) and not (_OPTION_FIELDS[key] is float and isinstance(value, int)):
            raise TaskFileError(f"{where}: option {key} must be {_OPTION_FIELDS[key].__name__}")
        if key == "inertial_torque_groups" and not all(isinstance(g, str) for g in value):
            raise TaskFileError(f"{where}: option inertial_torque_groups must be a list of group names")
        if key == "solver_options" and not all(isinstance(k, str) and isinstance(v, (str, int, float, bool))
                                               for k, v in value.items()):
            raise TaskFileError(f"{where}: option solver_options must map ipopt option names to numbers or strings")
        if key == "weights" and not all(isinstance(k, str) and isinstance(v, (int, float)) and not isinstance(v, bool)
                                        for k, v in value.items()):
            raise TaskFileError(f"{where}: option weights must map TO cost weight names to numbers")
        if key == "subtask_options" and not all(isinstance(k, int) and not isinstance(k, bool) and k >= 0
                                                and isinstance(v, dict) for k, v in value.items()):
            raise TaskFileError(f"{where}: option subtask_options must map subtask indices (0, 1, ...) to option "
                                "mappings")
    options = dict(options)
    if "weights" in options:
        options["weights"] = {k: float(v) for k, v in options["weights"].items()}
    if "solver_options" in options:  # as the message's text; YAML reads ipopt's yes/no as booleans
        options["solver_options"] = {k: ("yes" if v else "no") if isinstance(v, bool) else str(v)
                                     for k, v in options["solver_options"].items()}
    return Task(scenario, [p.strip() for p in prompts], dict(overrides), goals, options)


def _placement(entry, where: str) -> Placement:
    if not isinstance(entry, dict) or not isinstance(entry.get("object"), str):
        raise TaskFileError(f"{where} must be a mapping with 'object', 'position' [x, y, z] and 'yaw'")
    pos = entry.get("position")
    if not isinstance(pos, (list, tuple)) or len(pos) != 3:
        raise TaskFileError(f"{where}: 'position' must be [x, y, z] in metres")
    try:
        position = tuple(float(v) for v in pos)
        yaw = float(entry.get("yaw", 0.0))
    except (TypeError, ValueError) as exc:
        raise TaskFileError(f"{where}: position and yaw must be numbers") from exc
    if not all(math.isfinite(v) for v in (*position, yaw)):
        raise TaskFileError(f"{where}: position and yaw must be finite")
    return Placement(entry["object"], position, yaw)  # type: ignore[arg-type]
