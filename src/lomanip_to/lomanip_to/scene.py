"""Scene objects of the TO from the SAME scenario definition the simulator uses.

Why: the S1/S2 fixtures must not carry their own copy of box sizes, masses or shelf positions;
they would drift from the simulated world (they did: box 0.2 m vs 0.3 m tall, basket rim 1.42 vs
1.75 m).  :func:`scenario_scene` loads ``lomanip_sim.scenario`` parameters (``scenarios.yaml`` +
overrides such as box mass and yaw), compiles the world with ``lomanip_sim.world.build_world`` and
turns its object descriptions (collision primitives, mass, inertia, initial pose) into
:class:`~lomanip_to.problem.SceneObject` the same way ``conversions.scene_from_msg`` turns the sim's
``/lomanip/scene_objects`` message into them: frame moved to the centre of mass, cylinders lying on
their side (wheels, handle bar) passed as their bounding box, rear axle from the two rearmost wheels.

It also returns named frames for the fixtures (position + yaw in the world): one per object at the
sim's body origin (box: its centre; furniture and trolley: footprint centre on the floor), and
``<id>_com`` at its centre of mass (placement goals are written for the centre of mass).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .problem import INVALID_REQUEST, Primitive, ProblemError, SceneObject


@dataclass(frozen=True)
class Frame:
    """A planar frame: origin (world) and yaw about world z."""

    origin: np.ndarray
    yaw: float

    @property
    def R(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def point(self, p) -> np.ndarray:
        return self.origin + self.R @ np.asarray(p, float)

    def child(self, position, yaw: float = 0.0) -> "Frame":
        return Frame(self.point(position), self.yaw + float(yaw))


def _quat_wxyz_to_rot(q) -> np.ndarray:
    w, x, y, z = (float(v) for v in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _primitive(p, com: np.ndarray) -> Primitive:
    """lomanip_sim Primitive (MuJoCo sizes, object frame) -> TO Primitive (COM frame)."""
    pos = tuple(np.asarray(p.pos, float) - com)
    R = _quat_wxyz_to_rot(p.quat)
    yaw = math.atan2(R[1, 0], R[0, 0])
    if p.type == "box":
        if abs(R[2, 2]) > 0.999:
            return Primitive("box", tuple(2.0 * float(s) for s in p.size), pos, yaw)
        half = np.abs(R) @ np.asarray(p.size, float)
        return Primitive("box", tuple(2.0 * half), pos, 0.0)
    if p.type in ("cylinder", "capsule"):
        r, hl = float(p.size[0]), float(p.size[1])
        if p.type == "capsule":
            hl += r
        if abs(R[2, 2]) > 0.999:  # upright
            return Primitive("cylinder", (2.0 * hl, r), pos, yaw)
        half = np.abs(R) @ np.array([r, r, hl])  # lying on its side: bounding box (named simplification)
        return Primitive("box", tuple(2.0 * half), pos, 0.0)
    if p.type == "sphere":
        return Primitive("box", (2.0 * float(p.size[0]),) * 3, pos, 0.0)
    raise ProblemError(INVALID_REQUEST, f"unsupported primitive type {p.type!r}", "scene")


def objects_from_world(world) -> tuple[list[SceneObject], dict[str, Frame]]:
    """(SceneObjects with frames at the COM, frames at the sim's body origins) of a built world."""
    objects: list[SceneObject] = []
    frames: dict[str, Frame] = {}
    for oid, info in world.objects.items():
        R0 = _quat_wxyz_to_rot(info.initial_quat)
        yaw = math.atan2(R0[1, 0], R0[0, 0])
        com = np.asarray(info.com, float)
        pos = np.asarray(info.initial_pos, float) + R0 @ com
        prims = [_primitive(p, com) for p in info.primitives]
        wheels = sorted((tp for tp, sp in zip(prims, info.primitives) if "wheel" in sp.name),
                        key=lambda tp: tp.position[0])
        axle = tuple(np.mean([w.position for w in wheels[:2]], axis=0)) if len(wheels) >= 2 else (0.0, 0.0, 0.0)
        x, y, z, w = _rot_to_quat_xyzw(R0)
        objects.append(SceneObject(id=oid, object_class=info.object_class, movable=bool(info.movable),
                                   position=tuple(float(v) for v in pos), quat_xyzw=(x, y, z, w),
                                   mass=float(info.mass), inertia=tuple(map(tuple, np.asarray(info.inertia, float))),
                                   primitives=prims, rear_axle=axle))
        frames[oid] = Frame(np.asarray(info.initial_pos, float), yaw)
        frames[f"{oid}_com"] = Frame(pos, yaw)  # placement goals are centre-of-mass positions
    return objects, frames


def _rot_to_quat_xyzw(R: np.ndarray) -> tuple:
    from .model import rot_to_quat_xyzw

    return tuple(float(v) for v in rot_to_quat_xyzw(R))


def scenario_scene(name: str, overrides: dict | None = None):
    """(ScenarioParams, SceneObjects, frames) of lomanip_sim scenario ``name`` with ``overrides``.

    Raises :class:`ProblemError` (INVALID_REQUEST) for an unknown scenario or a bad parameter.
    """
    try:
        from lomanip_sim.scenario import ScenarioError, load_scenario
        from lomanip_sim.world import WorldBuildError, build_world
    except ImportError as exc:  # pragma: no cover - lomanip_sim is installed with the workspace
        raise ProblemError(INVALID_REQUEST, f"lomanip_sim is needed for scenario fixtures: {exc}", "scenario")
    try:
        params = load_scenario(name, overrides or {})
        world = build_world(params)
    except (ScenarioError, WorldBuildError) as exc:
        raise ProblemError(INVALID_REQUEST, str(exc), "scenario") from None
    objects, frames = objects_from_world(world)
    return params, objects, frames
