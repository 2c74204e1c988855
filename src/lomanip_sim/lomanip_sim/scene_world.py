"""MuJoCo world built from a plan's own scene description (for TO fixtures and TO benchmark results).

Why: a trajectory is only meaningful in the scene it was planned for. The S1/S2 worlds of
``world.py`` are the simulator's scenarios; the TO's test cases (stand, one step, lift a box) and
its hand-written scenario problems describe their own objects (boxes and upright cylinders, centre
of mass at the object frame). This module builds the same G1 world (torque motors, hand contact
boxes, floor, camera; see world.py) around those objects so the controller can execute the plan
under physics. Static objects are fixed bodies; movable ones get a free joint and their mass, with
a uniform-density inertia from their primitives.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from . import frames
from . import world as W
from .robot_model import G1_FREE_JOINT, G1_JOINT_NAMES, G1_STAND_QPOS, G1_TORQUE_LIMITS, g1_mjcf_path
from .scenario import CommonParams

_COLORS = {"box": (0.72, 0.52, 0.30, 1), "table": (0.5, 0.4, 0.3, 1), "shelf": (0.55, 0.55, 0.6, 1),
           "basket": (0.85, 0.75, 0.45, 1), "trolley": (0.25, 0.45, 0.75, 1)}  # fmt: skip


@dataclass(frozen=True)
class ScenePrimitive:
    kind: str  # "box" (size = full extents) | "cylinder" (size = (height, radius), axis z)
    size: tuple[float, ...]
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)  # in the object frame
    yaw: float = 0.0


@dataclass(frozen=True)
class SceneObjectSpec:
    id: str
    object_class: str
    movable: bool
    position: tuple[float, float, float]  # object frame origin (= centre of mass for movable ones)
    quat_wxyz: tuple[float, float, float, float]
    mass: float
    primitives: tuple[ScenePrimitive, ...]
    friction: float = 0.8


@dataclass(frozen=True)
class FixtureSceneParams(CommonParams):
    """Common parameters (physics, camera) of a world built from a plan's scene."""

    name = "plan_scene"
    camera_position: tuple = (2.2, -2.2, 1.6)
    camera_target: tuple = (0.4, 0.0, 0.6)


def scene_params(overrides: dict | None = None) -> FixtureSceneParams:
    """FixtureSceneParams with ``overrides`` (physics, camera) checked as a scenario's are (ScenarioError)."""
    return FixtureSceneParams().replace(**(overrides or {}))


def objects_from_to_problem(prob) -> list[SceneObjectSpec]:
    """lomanip_to Problem.objects (duck typed: id, object_class, movable, position, quat_xyzw, mass,
    primitives with kind/size/position/yaw) -> SceneObjectSpec list."""
    out = []
    for o in prob.objects:
        prims = tuple(ScenePrimitive(p.kind, tuple(float(s) for s in p.size), tuple(float(v) for v in p.position),
                                     float(p.yaw)) for p in o.primitives)  # fmt: skip
        out.append(SceneObjectSpec(o.id, o.object_class, bool(o.movable), tuple(float(v) for v in o.position),
                                   tuple(frames.xyzw_to_wxyz(o.quat_xyzw)), float(o.mass), prims))  # fmt: skip
    return out


def _add_object(spec: mujoco.MjSpec, o: SceneObjectSpec) -> None:
    body = spec.worldbody.add_body()
    body.name = o.id
    body.pos = list(o.position)
    body.quat = list(o.quat_wxyz)
    if o.movable:
        if o.mass <= 0:
            raise W.WorldBuildError(f"movable object {o.id!r} needs a positive mass, got {o.mass}")
        body.add_freejoint().name = f"{o.id}_free"
        vols = [np.prod(p.size) if p.kind == "box" else np.pi * p.size[1] ** 2 * p.size[0] for p in o.primitives]
        rho = o.mass / max(sum(vols), 1e-9)
    rgba = _COLORS.get(o.object_class, (0.6, 0.6, 0.6, 1))
    for k, p in enumerate(o.primitives):
        q = frames.yaw_to_quat(p.yaw)
        if p.kind == "box":
            size = tuple(s / 2 for s in p.size)
            gtype = "box"
        elif p.kind == "cylinder":
            size = (p.size[1], p.size[0] / 2)
            gtype = "cylinder"
        else:
            raise W.WorldBuildError(f"object {o.id!r}: unsupported primitive kind {p.kind!r}")
        W._add_geom(body, f"{o.id}_geom{k}", gtype, size, p.position, q, rgba=rgba,
                    density=rho if o.movable else None, friction=o.friction)  # fmt: skip


def build_scene_world(objects: list[SceneObjectSpec], robot_qpos: np.ndarray | None = None,
                      params: FixtureSceneParams | None = None) -> W.World:  # fmt: skip
    """Compile the G1 + ``objects`` world; the 'stand' key puts the robot at ``robot_qpos`` (36-D)."""
    params = params or FixtureSceneParams()
    try:
        spec = mujoco.MjSpec.from_file(str(g1_mjcf_path()))
    except Exception as e:  # mujoco raises plain ValueError on parse problems
        raise W.WorldBuildError(f"cannot load {g1_mjcf_path()}: {e}") from e
    spec.modelname = "lomanip_plan_scene"
    W.set_physics_options(spec, params)
    for key in list(spec.keys):
        spec.delete(key)
    W._convert_actuators_to_motors(spec)
    W._add_hands(spec)
    W._setup_visual(spec, params)
    W._add_floor_light_camera(spec, params)
    for o in objects:
        _add_object(spec, o)
    spec.add_key().name = "stand"
    try:
        model = spec.compile()
    except Exception as e:
        raise W.WorldBuildError(f"MuJoCo could not compile the plan's scene: {e}") from e

    stand = model.qpos0.copy()
    a = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, G1_FREE_JOINT)]
    stand[a : a + 36] = G1_STAND_QPOS if robot_qpos is None else np.asarray(robot_qpos, float)
    kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "stand")
    model.key_qpos[kid] = stand
    model.key_ctrl[kid] = 0.0
    jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in G1_JOINT_NAMES]
    aids = [int(np.nonzero(model.actuator_trnid[:, 0] == j)[0][0]) for j in jids]
    data = mujoco.MjData(model)
    data.qpos[:] = stand
    mujoco.mj_kinematics(model, data)
    infos = {o.id: W._object_info(model, data, o.id, o.object_class) for o in objects}
    return W.World(model=model, params=params, objects=infos, stand_qpos=stand,
                   joint_qpos_adr=np.array([model.jnt_qposadr[j] for j in jids]),
                   joint_dof_adr=np.array([model.jnt_dofadr[j] for j in jids]), actuator_ids=np.array(aids),
                   torque_limits=np.array([G1_TORQUE_LIMITS[j] for j in G1_JOINT_NAMES]))  # fmt: skip
