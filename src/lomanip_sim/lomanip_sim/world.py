"""Programmatic MuJoCo world (G1 + scenario scene) built with ``mujoco.MjSpec``.

Why: scenario parameters are inputs, so the scene is composed from them at run time instead of
from hand-written XML. The G1 comes unmodified from Menagerie's ``g1.xml`` with four changes made
in the spec (the file on disk is never touched):

* its 29 position servos become torque motors (``ctrlrange`` = rev 1.0 torque limits), because the
  whole-body controller commands torques;
* hand contact sites ``left_hand``/``right_hand`` and box-shaped hand collision proxies are added
  (the Menagerie rubber hands are visual-only; added geoms do not change the link masses);
* the ``stand`` keyframe is rebuilt for the full world (robot stand pose + object poses);
* lights cast no shadows and visual quality is set for fast offscreen rendering (measured here:
  28 fps instead of 3.5 fps at 640x480).

Each scenario object is a body named by its stable id with a class (box, shelf, basket, table,
trolley); :class:`ObjectInfo` exposes its collision primitives (MuJoCo half-size convention, posed
in the object frame), mass and inertia for publishing as scene objects.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from . import frames
from .robot_model import (
    G1_FREE_JOINT,
    G1_JOINT_NAMES,
    G1_STAND_QPOS,
    G1_TORQUE_LIMITS,
    HAND_BODIES,
    HAND_COLLISION_HALF_SIZE,
    HAND_CONTACT_OFFSET,
    HAND_SITES,
    g1_mjcf_path,
)
from .scenario import FRICTION_CONES, CommonParams, S1BasketParams, S2TrolleyParams, ScenarioParams

SCENE_CAMERA = "scene_camera"
FLOOR_GEOM = "floor"
#: Mass of each caster fork (taken out of trolley_mass, so the chassis+handle+forks = trolley_mass).
CASTER_FORK_MASS = 0.05

_GEOM_TYPES = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
}
_GEOM_NAMES = {v: k for k, v in _GEOM_TYPES.items()}
_Q_X90 = frames.axis_angle_to_quat([1, 0, 0], np.pi / 2)  # cylinder axis z -> y


class WorldBuildError(RuntimeError):
    """The MuJoCo world could not be built from the given parameters."""


@dataclass(frozen=True)
class Primitive:
    """One collision primitive of an object, posed in the object frame.

    ``size`` follows MuJoCo: box = half extents (3), sphere = (radius,), cylinder/capsule =
    (radius, half length). :meth:`solid_primitive_dimensions` gives shape_msgs/SolidPrimitive's.
    """

    name: str
    type: str  # "box" | "sphere" | "cylinder" | "capsule"
    size: tuple[float, ...]
    pos: np.ndarray  # (3,) in the object frame
    quat: np.ndarray  # (4,) (w,x,y,z) in the object frame

    def solid_primitive_dimensions(self) -> list[float]:
        """shape_msgs/SolidPrimitive dimensions: BOX [x,y,z] full, SPHERE [r], CYLINDER/CAPSULE [h, r]."""
        if self.type == "box":
            return [2.0 * s for s in self.size]
        if self.type == "sphere":
            return [self.size[0]]
        return [2.0 * self.size[1], self.size[0]]


@dataclass(frozen=True)
class ObjectInfo:
    """A scenario object: stable id, class, its body, mass properties and collision geometry."""

    id: str
    object_class: str
    body_name: str
    movable: bool
    mass: float  # kg, whole object incl. wheels (0 for static furniture)
    com: np.ndarray  # (3,) in the object frame
    inertia: np.ndarray  # (3,3) about the CoM, object frame axes (zeros for static furniture)
    primitives: tuple[Primitive, ...]
    initial_pos: np.ndarray  # (3,) world
    initial_quat: np.ndarray  # (4,) (w,x,y,z) world


@dataclass
class World:
    """A compiled world: model, objects and the indices the simulator needs."""

    model: mujoco.MjModel
    params: ScenarioParams
    objects: dict[str, ObjectInfo]
    stand_qpos: np.ndarray  # full-world qpos of the 'stand' keyframe
    joint_qpos_adr: np.ndarray  # qpos index of each G1 joint (G1_JOINT_NAMES order)
    joint_dof_adr: np.ndarray  # qvel index of each G1 joint
    actuator_ids: np.ndarray  # actuator index per G1 joint
    torque_limits: np.ndarray  # (29,) N m
    camera_name: str = SCENE_CAMERA
    extra: dict = field(default_factory=dict)

    @property
    def scenario(self) -> str:
        return self.params.name


# ---------------------------------------------------------------------------------------------
# spec helpers


def _box_volume(h) -> float:
    return 8.0 * h[0] * h[1] * h[2]


def _add_geom(body, name, gtype, size, pos=(0, 0, 0), quat=(1, 0, 0, 0), rgba=(0.6, 0.6, 0.6, 1), *,
              density=None, mass=None, friction=None, collide=True, group=0):  # fmt: skip
    g = body.add_geom()
    g.name = name
    g.type = _GEOM_TYPES[gtype]
    s = list(size) + [0.0] * (3 - len(size))
    g.size = s
    g.pos = list(pos)
    g.quat = list(quat)
    g.rgba = list(rgba)
    g.group = group
    if mass is not None:
        g.mass = mass
    if density is not None:
        g.density = density
    if friction is not None:
        g.friction = [friction, 0.005, 0.0001]
    if not collide:
        g.contype = 0
        g.conaffinity = 0
    return g


def _convert_actuators_to_motors(spec: mujoco.MjSpec) -> None:
    for act in spec.actuators:
        joint = act.target
        if joint not in G1_TORQUE_LIMITS:
            raise WorldBuildError(f"unexpected actuator target {joint!r} in g1.xml")
        act.set_to_motor()
        act.inheritrange = 0.0
        lim = G1_TORQUE_LIMITS[joint]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [-lim, lim]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-lim, lim]


def _add_hands(spec: mujoco.MjSpec) -> None:
    for side, body_name in HAND_BODIES.items():
        body = spec.body(body_name)
        site = body.add_site()
        site.name = HAND_SITES[side]
        site.pos = list(HAND_CONTACT_OFFSET[side])
        site.size = [0.01, 0.01, 0.01]
        site.group = 5
        g = _add_geom(body, f"{side}_hand_collision", "box", HAND_COLLISION_HALF_SIZE, HAND_CONTACT_OFFSET[side],
                      rgba=(0.2, 0.2, 0.2, 1), mass=0.0, group=3)  # fmt: skip
        g.priority = 1
        g.friction = [1.0, 0.005, 0.0001]  # rubber


def _setup_visual(spec: mujoco.MjSpec, p: ScenarioParams) -> None:
    vis = spec.visual
    vis.quality.shadowsize = 0
    vis.quality.offsamples = 0
    vis.global_.offwidth = max(int(p.camera_width), 640)
    vis.global_.offheight = max(int(p.camera_height), 480)
    vis.headlight.ambient = [0.35, 0.35, 0.35]
    vis.headlight.diffuse = [0.5, 0.5, 0.5]
    vis.headlight.specular = [0.1, 0.1, 0.1]
    vis.map.znear = 0.005  # relative to the model extent: a few mm, fine depth near the camera
    for light in spec.lights:
        light.castshadow = False
    tex = spec.add_texture()
    tex.name = "floor_checker"
    tex.type = mujoco.mjtTexture.mjTEXTURE_2D
    tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
    tex.rgb1 = [0.45, 0.45, 0.45]
    tex.rgb2 = [0.35, 0.35, 0.35]
    tex.width = 256
    tex.height = 256
    mat = spec.add_material()
    mat.name = "floor_mat"
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "floor_checker"
    mat.texrepeat = [1.0, 1.0]
    mat.texuniform = True
    mat.reflectance = 0.0


def _add_floor_light_camera(spec: mujoco.MjSpec, p: ScenarioParams) -> None:
    wb = spec.worldbody
    floor = wb.add_geom()
    floor.name = FLOOR_GEOM
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0, 0, 0.05]
    floor.material = "floor_mat"
    floor.friction = [p.floor_friction, 0.005, 0.0001]
    light = wb.add_light()
    light.name = "scene_light"
    light.pos = [1.0, 0.0, 4.0]
    light.dir = [0.0, 0.2, -1.0]
    light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    light.castshadow = False
    light.diffuse = [0.5, 0.5, 0.5]
    cam = wb.add_camera()
    cam.name = SCENE_CAMERA
    cam.pos = list(p.camera_position)
    cam.quat = list(frames.look_at_mujoco_camera_quat(p.camera_position, p.camera_target))
    cam.fovy = float(p.camera_fovy)
    cam.resolution = [int(p.camera_width), int(p.camera_height)]


def _yaw_xy(center_xy, yaw, local_xy) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([center_xy[0] + c * local_xy[0] - s * local_xy[1], center_xy[1] + s * local_xy[0] + c * local_xy[1]])


def _add_box_object(spec, name, size, xy, z_bottom, yaw, mass, friction, rgba) -> None:
    h = np.asarray(size) / 2.0
    body = spec.worldbody.add_body()
    body.name = name
    body.pos = [xy[0], xy[1], z_bottom + h[2]]
    body.quat = list(frames.yaw_to_quat(yaw))
    body.add_freejoint().name = f"{name}_free"
    _add_geom(body, f"{name}_geom", "box", h, rgba=rgba, mass=mass, friction=friction)


def _add_table_like(spec, name, size, xy, yaw, top_thickness, leg, rgba, mid_board=False) -> None:
    """Static furniture: top board at height size[2], four legs, optional middle board (shelf)."""
    d, w, H = size
    body = spec.worldbody.add_body()
    body.name = name
    body.pos = [xy[0], xy[1], 0.0]
    body.quat = list(frames.yaw_to_quat(yaw))
    _add_geom(body, f"{name}_top", "box", (d / 2, w / 2, top_thickness / 2), (0, 0, H - top_thickness / 2), rgba=rgba)
    leg_h = (H - top_thickness) / 2
    for i, (sx, sy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        pos = (sx * (d / 2 - leg / 2), sy * (w / 2 - leg / 2), leg_h)
        _add_geom(body, f"{name}_leg{i}", "box", (leg / 2, leg / 2, leg_h), pos, rgba=rgba)
    if mid_board:
        _add_geom(body, f"{name}_board", "box", (d / 2 - leg, w / 2 - leg, top_thickness / 2), (0, 0, H / 2), rgba=rgba)


def _add_basket(spec, p: S1BasketParams) -> None:
    d, w, h = p.basket_size
    t = min(p.basket_wall, 0.25 * min(d, w, h))
    sd, sw, sh = p.shelf_size
    local = (-sd / 2 + p.basket_setback + d / 2, 0.0)
    xy = _yaw_xy(p.shelf_position, p.shelf_yaw, local)
    body = spec.worldbody.add_body()
    body.name = "basket"
    body.pos = [xy[0], xy[1], sh]
    body.quat = list(frames.yaw_to_quat(p.shelf_yaw))
    body.add_freejoint().name = "basket_free"
    hw = (h - t) / 2
    parts = [
        ("bottom", (d / 2, w / 2, t / 2), (0, 0, t / 2)),
        # Walls stand on the bottom plate (not on the shelf): fewer resting contacts, faster physics.
        ("front", (t / 2, w / 2, hw), (-d / 2 + t / 2, 0, t + hw)),
        ("back", (t / 2, w / 2, hw), (d / 2 - t / 2, 0, t + hw)),
        ("left", (d / 2 - t, t / 2, hw), (0, w / 2 - t / 2, t + hw)),
        ("right", (d / 2 - t, t / 2, hw), (0, -w / 2 + t / 2, t + hw)),
    ]
    rho = p.basket_mass / sum(_box_volume(s) for _, s, _ in parts)
    for nm, s, pos in parts:
        _add_geom(body, f"basket_{nm}", "box", s, pos, rgba=(0.85, 0.75, 0.45, 1), density=rho, friction=0.8)


def _add_trolley(spec, p: S2TrolleyParams) -> None:
    L, W, Hdeck = p.trolley_size
    r = p.wheel_radius
    t = 0.03  # deck thickness
    if Hdeck - t < 2 * r + 0.02:
        raise WorldBuildError(f"trolley deck height {Hdeck} m leaves no room for wheels of radius {r} m")
    if p.trolley_handle_height <= Hdeck:
        raise WorldBuildError("trolley_handle_height must be above the deck (trolley_size[2])")
    body = spec.worldbody.add_body()
    body.name = "trolley"
    body.pos = [p.trolley_position[0], p.trolley_position[1], 0.0]
    body.quat = list(frames.yaw_to_quat(p.trolley_yaw))
    body.add_freejoint().name = "trolley_free"
    wy = W / 2 - 0.04  # wheel track half width
    x_rear, x_front = -L / 2 + 0.10, L / 2 - 0.10
    post_r, bar_r = 0.015, 0.016
    x_handle = -L / 2 + post_r
    post_half = (p.trolley_handle_height - Hdeck) / 2
    leg_half = (Hdeck - t - r) / 2
    parts = [
        # (name, type, size, pos, quat, collide)
        ("deck", "box", (L / 2, W / 2, t / 2), (0, 0, Hdeck - t / 2), (1, 0, 0, 0), True),
        ("post_l", "cylinder", (post_r, post_half), (x_handle, wy, Hdeck + post_half), (1, 0, 0, 0), True),
        ("post_r", "cylinder", (post_r, post_half), (x_handle, -wy, Hdeck + post_half), (1, 0, 0, 0), True),
        ("handle", "cylinder", (bar_r, wy + post_r), (x_handle, 0, p.trolley_handle_height), _Q_X90, True),
    ]
    for i, (x, y) in enumerate([(x_rear, wy), (x_rear, -wy), (x_front, wy), (x_front, -wy)]):
        parts.append((f"strut{i}", "box", (0.012, 0.012, leg_half), (x, y, r + leg_half), (1, 0, 0, 0), False))
    vol = sum(_box_volume(s) if ty == "box" else np.pi * s[0] ** 2 * 2 * s[1] for _, ty, s, _, _, _ in parts)
    rho = (p.trolley_mass - 2 * CASTER_FORK_MASS) / vol
    if rho <= 0:
        raise WorldBuildError(f"trolley_mass {p.trolley_mass} kg is below the caster forks' {2 * CASTER_FORK_MASS} kg")
    for nm, ty, s, pos, q, col in parts:
        _add_geom(body, f"trolley_{nm}", ty, s, pos, q, rgba=(0.25, 0.45, 0.75, 1), density=rho, collide=col)
    wheel_half_w = 0.02

    def add_wheel(parent, name, pos):
        wb = parent.add_body()
        wb.name = name
        wb.pos = list(pos)
        j = wb.add_joint()
        j.name = f"{name}_roll"
        j.type = mujoco.mjtJoint.mjJNT_HINGE
        j.axis = [0, 1, 0]
        j.damping = [0.002, 0.0, 0.0]
        j.frictionloss = p.wheel_rolling_resistance * r  # rolling resistance (see S2TrolleyParams)
        _add_geom(wb, f"{name}_geom", "cylinder", (r, wheel_half_w), quat=_Q_X90, rgba=(0.1, 0.1, 0.1, 1),
                  mass=p.wheel_mass, friction=1.0)  # fmt: skip

    # Rear wheels: plain hinges (roll about the axle, no lateral slip thanks to friction).
    add_wheel(body, "trolley_wheel_rl", (x_rear, wy, r))
    add_wheel(body, "trolley_wheel_rr", (x_rear, -wy, r))
    # Front casters: vertical swivel hinge, wheel trailing behind the swivel axis.
    for side, y in (("l", wy), ("r", -wy)):
        fork = body.add_body()
        fork.name = f"trolley_caster_f{side}"
        fork.pos = [x_front, y, r]
        j = fork.add_joint()
        j.name = f"trolley_caster_f{side}_swivel"
        j.type = mujoco.mjtJoint.mjJNT_HINGE
        j.axis = [0, 0, 1]
        j.damping = [0.002, 0.0, 0.0]
        j.armature = 0.0005
        _add_geom(fork, f"trolley_caster_f{side}_fork", "box", (0.015, 0.03, 0.01), (-p.caster_trail / 2, 0, r + 0.005),
                  rgba=(0.3, 0.3, 0.3, 1), mass=CASTER_FORK_MASS, collide=False)  # fmt: skip
        add_wheel(fork, f"trolley_wheel_f{side}", (-p.caster_trail, 0, 0))


def _add_scenario_objects(spec, p: ScenarioParams) -> list[tuple[str, str]]:
    """Adds the scenario bodies; returns [(id, class)]."""
    if isinstance(p, S1BasketParams):
        _add_box_object(spec, "box", p.box_size, p.box_position, 0.0, p.box_yaw, p.box_mass, p.box_friction,
                        (0.72, 0.52, 0.30, 1))  # fmt: skip
        _add_table_like(spec, "shelf", p.shelf_size, p.shelf_position, p.shelf_yaw, 0.03, 0.04,
                        (0.55, 0.35, 0.2, 1), mid_board=True)  # fmt: skip
        _add_basket(spec, p)
        return [("box", "box"), ("shelf", "shelf"), ("basket", "basket")]
    if isinstance(p, S2TrolleyParams):
        td, tw, th = p.table_size
        xy = _yaw_xy(p.table_position, p.table_yaw, p.box_offset)
        _add_box_object(spec, "box", p.box_size, xy, th, p.box_yaw, p.box_mass, p.box_friction, (0.72, 0.52, 0.30, 1))
        _add_table_like(spec, "table", p.table_size, p.table_position, p.table_yaw, 0.04, 0.05, (0.5, 0.4, 0.3, 1))
        _add_trolley(spec, p)
        return [("box", "box"), ("table", "table"), ("trolley", "trolley")]
    raise WorldBuildError(f"no world builder for parameters of type {type(p).__name__}")


# ---------------------------------------------------------------------------------------------
# object descriptions from the compiled model


def _subtree(model: mujoco.MjModel, root: int) -> list[int]:
    out = []
    for b in range(model.nbody):
        a = b
        while a > 0 and a != root:
            a = model.body_parentid[a]
        if a == root:
            out.append(b)
    return out


def _object_info(model, data, oid: str, cls: str) -> ObjectInfo:
    root = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, oid)
    bodies = _subtree(model, root)
    p0 = data.xpos[root].copy()
    R0 = data.xmat[root].reshape(3, 3).copy()
    q0 = data.xquat[root].copy()
    movable = model.body_jntnum[root] > 0
    prims = []
    for b in bodies:
        for g in range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b]):
            if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
                continue
            gtype = _GEOM_NAMES.get(int(model.geom_type[g]))
            if gtype is None:
                continue
            n = {"box": 3, "sphere": 1, "cylinder": 2, "capsule": 2}[gtype]
            pos = R0.T @ (data.geom_xpos[g] - p0)
            Rg = R0.T @ data.geom_xmat[g].reshape(3, 3)
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"{oid}_geom{g}"
            prims.append(Primitive(name, gtype, tuple(float(s) for s in model.geom_size[g][:n]), pos, frames.matrix_to_quat(Rg)))
    if movable:
        mass = float(sum(model.body_mass[b] for b in bodies))
        com_w = sum(model.body_mass[b] * data.xipos[b] for b in bodies) / mass
        I = np.zeros((3, 3))
        for b in bodies:
            Rb = data.ximat[b].reshape(3, 3)
            Ib = Rb @ np.diag(model.body_inertia[b]) @ Rb.T
            r = data.xipos[b] - com_w
            I += Ib + model.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
        com = R0.T @ (com_w - p0)
        inertia = R0.T @ I @ R0
    else:
        mass, com, inertia = 0.0, np.zeros(3), np.zeros((3, 3))
    return ObjectInfo(oid, cls, oid, bool(movable), mass, com, inertia, tuple(prims), p0, q0)


# ---------------------------------------------------------------------------------------------


def set_physics_options(spec: mujoco.MjSpec, params: CommonParams) -> None:
    """MuJoCo's solver options from the scenario (see CommonParams), for every world built here."""
    spec.option.timestep = float(params.timestep)
    spec.option.noslip_iterations = int(params.noslip_iterations)
    spec.option.impratio = float(params.impratio)
    spec.option.cone = FRICTION_CONES.index(params.friction_cone)


def build_spec(params: ScenarioParams) -> tuple[mujoco.MjSpec, list[tuple[str, str]]]:
    """The MjSpec of the world (G1 + scene) before compilation; also returns [(object id, class)]."""
    try:
        spec = mujoco.MjSpec.from_file(str(g1_mjcf_path()))
    except Exception as e:  # mujoco raises plain ValueError on parse problems
        raise WorldBuildError(f"cannot load {g1_mjcf_path()}: {e}") from e
    spec.modelname = f"lomanip_{params.name}"
    set_physics_options(spec, params)
    for key in list(spec.keys):
        spec.delete(key)
    _convert_actuators_to_motors(spec)
    _add_hands(spec)
    _setup_visual(spec, params)
    _add_floor_light_camera(spec, params)
    objects = _add_scenario_objects(spec, params)
    k = spec.add_key()
    k.name = "stand"
    return spec, objects


def build_world(params: ScenarioParams) -> World:
    """Compile the world for ``params`` and describe its objects."""
    spec, object_ids = build_spec(params)
    try:
        model = spec.compile()
    except Exception as e:
        raise WorldBuildError(f"MuJoCo could not compile the {params.name} world: {e}") from e

    stand = model.qpos0.copy()
    fj = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, G1_FREE_JOINT)
    a = model.jnt_qposadr[fj]
    robot_q = G1_STAND_QPOS.copy()
    robot_q[0:2] = params.robot_position
    robot_q[3:7] = frames.yaw_to_quat(params.robot_yaw)
    stand[a : a + 36] = robot_q
    kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "stand")
    model.key_qpos[kid] = stand
    model.key_ctrl[kid] = 0.0

    jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in G1_JOINT_NAMES]
    aids = []
    for j in jids:
        ids = np.nonzero(model.actuator_trnid[:, 0] == j)[0]
        if len(ids) != 1:
            raise WorldBuildError(f"joint {model.joint(j).name} has {len(ids)} actuators, expected 1")
        aids.append(int(ids[0]))
    limits = np.array([G1_TORQUE_LIMITS[j] for j in G1_JOINT_NAMES])
    if not np.allclose(model.actuator_ctrlrange[aids, 1], limits):
        raise WorldBuildError("actuator ctrlrange does not match the G1 torque limits")

    data = mujoco.MjData(model)
    data.qpos[:] = stand
    mujoco.mj_kinematics(model, data)
    objects = {oid: _object_info(model, data, oid, cls) for oid, cls in object_ids}
    return World(
        model=model,
        params=params,
        objects=objects,
        stand_qpos=stand,
        joint_qpos_adr=np.array([model.jnt_qposadr[j] for j in jids]),
        joint_dof_adr=np.array([model.jnt_dofadr[j] for j in jids]),
        actuator_ids=np.array(aids),
        torque_limits=limits,
    )


def build_robot_model() -> mujoco.MjModel:
    """The G1 alone (no scene): g1.xml plus the hand sites and hand collision proxies of the world.

    For kinematic users (IK retargeting, visualisation) that need the same frames as the sim.
    """
    try:
        spec = mujoco.MjSpec.from_file(str(g1_mjcf_path()))
    except Exception as e:  # mujoco raises plain ValueError on parse problems
        raise WorldBuildError(f"cannot load {g1_mjcf_path()}: {e}") from e
    _convert_actuators_to_motors(spec)
    _add_hands(spec)
    return spec.compile()
