"""Simulation: the MuJoCo world of one scenario, stepped with a torque controller.

Why: the ROS sim node, the tests and offline scripts all need the same thing: build the world from
scenario parameters, start the G1 standing, step physics at the model timestep with a controller
computing torques every step (the standing controller by default, or an external one / a raw
torque command), read named joint states, base and object poses, push the robot, and tell whether
it fell. Physics is guarded by a lock so a renderer thread can copy ``qpos`` consistently
(:meth:`Simulation.snapshot`) while another thread steps.

Each step is ``mj_step1`` (kinematics + bias forces of the current state) -> controller ->
``mj_step2`` (dynamics + integration), so the controller sees up-to-date quantities at no extra
cost. Nothing here freezes the base, welds the robot or writes ``qpos`` during a run.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Protocol

import mujoco
import numpy as np

from . import frames
from .robot_model import FOOT_SITES, G1_FREE_JOINT, G1_JOINT_NAMES, PELVIS_BODY, TORSO_BODY
from .scenario import ScenarioParams, load_scenario
from .standing import StandingController, StandingGains
from .world import ObjectInfo, Primitive, World, build_world


class SimulationError(RuntimeError):
    """Invalid request to the simulation (unknown body/object id, bad torque vector, ...)."""


class TorqueController(Protocol):
    """Anything that maps the current MjData to 29 joint torques (G1_JOINT_NAMES order)."""

    def reset(self, data: mujoco.MjData) -> None: ...

    def compute(self, data: mujoco.MjData) -> np.ndarray: ...

    # optional: ``observe(data)``, called after each step's mj_step2 (contact forces of that step)


@dataclass(frozen=True)
class SimSnapshot:
    """A consistent copy of the state (for renderers and publishers)."""

    time: float
    qpos: np.ndarray
    qvel: np.ndarray


@dataclass(frozen=True)
class ObjectState:
    """A scenario object's description and current state (world frame, MuJoCo quaternion order)."""

    id: str
    object_class: str
    movable: bool
    pos: np.ndarray  # (3,)
    quat: np.ndarray  # (4,) (w,x,y,z)
    linvel: np.ndarray  # (3,) world velocity of the object frame origin
    angvel: np.ndarray  # (3,) world angular velocity
    mass: float
    com: np.ndarray  # (3,) object frame
    inertia: np.ndarray  # (3,3) about the CoM, object frame
    primitives: tuple[Primitive, ...]

    @property
    def quat_xyzw(self) -> np.ndarray:
        """Orientation in ROS order (x,y,z,w)."""
        return frames.wxyz_to_xyzw(self.quat)


@dataclass
class _Push:
    body: int
    force: np.ndarray
    torque: np.ndarray
    t_end: float
    point_local: np.ndarray | None  # application point in the body frame (None: at the body CoM)


@dataclass(frozen=True)
class FallCriteria:
    """When has_fallen() says the robot is down."""

    min_pelvis_height: float = 0.35  # m above the world floor
    min_pelvis_above_feet: float = 0.40  # m, pelvis height above the lowest foot site
    max_tilt: float = 0.8  # rad, pelvis or torso z axis vs vertical
    # While a plan executes (Execution), the thresholds give way where the plan itself goes below or
    # beyond them (S1 squats to pelvis 0.30 m and bends the torso 1.35 rad): a fall is then the
    # pelvis this far below the planned height (absolute and above the feet) or a tilt this far past
    # the planned one. Has no effect on has_fallen() (no plan there).
    plan_height_margin: float = 0.15  # m
    plan_tilt_margin: float = 0.4  # rad


class Simulation:
    """One scenario world, stepped under a torque controller. Thread-safe for step vs snapshot."""

    def __init__(self, params: ScenarioParams | None = None, gains: StandingGains | None = None,
                 fall: FallCriteria | None = None):  # fmt: skip
        self._lock = threading.RLock()
        self._gains = gains
        self.fall_criteria = fall or FallCriteria()
        self._build(params if params is not None else load_scenario("s1_basket"))

    # ------------------------------------------------------------------ construction / reset
    def _build(self, params: ScenarioParams) -> None:
        self.world: World = params if isinstance(params, World) else build_world(params)
        self.model: mujoco.MjModel = self.world.model
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PELVIS_BODY)
        self._torso = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, TORSO_BODY)
        fj = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, G1_FREE_JOINT)
        self._base_q = int(m.jnt_qposadr[fj])
        self._base_v = int(m.jnt_dofadr[fj])
        self._foot_sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for s in FOOT_SITES.values()]
        self._obj_body = {oid: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, o.body_name) for oid, o in self.world.objects.items()}
        self.standing = StandingController(m, self.world.joint_qpos_adr, self.world.joint_dof_adr,
                                           self.world.torque_limits, gains=self._gains)  # fmt: skip
        self.controller: TorqueController = self.standing
        self._pushes: list[_Push] = []
        self._command: np.ndarray | None = None
        self.last_torques = np.zeros(len(G1_JOINT_NAMES))
        self._reset_state()

    def _reset_state(self) -> None:
        mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        mujoco.mj_forward(self.model, self.data)
        self._pushes.clear()
        self._command = None
        self.standing.reset(self.data)
        if self.controller is not self.standing:
            self.controller.reset(self.data)

    def reset(self, new_params: ScenarioParams | None = None) -> None:
        """Back to the standing keyframe; with ``new_params`` the world is rebuilt first."""
        with self._lock:
            if new_params is not None:
                self._build(new_params)
            else:
                self._reset_state()

    @property
    def params(self) -> ScenarioParams:
        return self.world.params

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    @property
    def time(self) -> float:
        return float(self.data.time)

    # ------------------------------------------------------------------ control
    def set_controller(self, controller: TorqueController | None) -> None:
        """Use ``controller`` each step (None: back to the standing controller)."""
        with self._lock:
            self.controller = controller if controller is not None else self.standing
            self.controller.reset(self.data)

    def set_torque_command(self, torques: np.ndarray | Mapping[str, float] | None) -> None:
        """Hold a raw joint torque command (clipped to limits) instead of the controller; None clears."""
        with self._lock:
            self._command = None if torques is None else self._torque_vector(torques)

    def _torque_vector(self, torques) -> np.ndarray:
        if isinstance(torques, Mapping):
            unknown = set(torques) - set(G1_JOINT_NAMES)
            if unknown:
                raise SimulationError(f"unknown joint names in torque command: {sorted(unknown)}")
            tau = np.zeros(len(G1_JOINT_NAMES))
            for i, j in enumerate(G1_JOINT_NAMES):
                tau[i] = torques.get(j, 0.0)
        else:
            tau = np.asarray(torques, dtype=float).reshape(-1)
            if tau.shape != (len(G1_JOINT_NAMES),):
                raise SimulationError(f"torque command needs {len(G1_JOINT_NAMES)} values, got {tau.shape}")
        if not np.all(np.isfinite(tau)):
            raise SimulationError("torque command contains NaN/inf")
        return np.clip(tau, -self.world.torque_limits, self.world.torque_limits)

    def apply_external_force(self, body_name: str, force_xyz, duration: float, torque_xyz=(0.0, 0.0, 0.0),
                             point_world=None) -> None:  # fmt: skip
        """Push ``body_name`` with a world-frame force (N) [and torque] for ``duration`` s.

        The force acts at the body CoM, or at ``point_world`` (a world point at the time of the call
        that then moves with the body, e.g. a trolley handle).
        """
        bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, body_name)
        if bid < 0:
            raise SimulationError(f"unknown body {body_name!r}")
        if duration <= 0:
            raise SimulationError("push duration must be > 0")
        with self._lock:
            local = None
            if point_world is not None:
                R = self.data.xmat[bid].reshape(3, 3)
                local = R.T @ (np.asarray(point_world, float) - self.data.xpos[bid])
            self._pushes.append(_Push(bid, np.asarray(force_xyz, float), np.asarray(torque_xyz, float),
                                      self.data.time + duration, local))  # fmt: skip

    def step(self, n: int = 1, torques: np.ndarray | Mapping[str, float] | None = None) -> None:
        """Advance ``n`` physics steps. ``torques`` (29 or by name) overrides the controller for them."""
        m, d = self.model, self.data
        cmd = self._torque_vector(torques) if torques is not None else None
        aids = self.world.actuator_ids
        with self._lock:
            for _ in range(n):
                mujoco.mj_step1(m, d)
                tau = cmd if cmd is not None else self._command
                if tau is None:
                    tau = self.controller.compute(d)
                d.ctrl[aids] = tau
                self.last_torques = tau
                d.xfrc_applied[:] = 0.0
                if self._pushes:
                    self._pushes = [p for p in self._pushes if p.t_end > d.time + 1e-12]
                    for p in self._pushes:
                        d.xfrc_applied[p.body, 0:3] += p.force
                        d.xfrc_applied[p.body, 3:6] += p.torque
                        if p.point_local is not None:  # moment of the force about the CoM
                            r = d.xpos[p.body] + d.xmat[p.body].reshape(3, 3) @ p.point_local - d.xipos[p.body]
                            d.xfrc_applied[p.body, 3:6] += np.cross(r, p.force)
                mujoco.mj_step2(m, d)
                if cmd is None and self._command is None:
                    observe = getattr(self.controller, "observe", None)
                    if observe is not None:  # contact forces of this step (valid only after mj_step2)
                        observe(d)

    def run_for(self, seconds: float) -> None:
        """Step for ``seconds`` of simulated time."""
        self.step(int(round(seconds / self.timestep)))

    def real_time_factor(self, sim_seconds: float = 1.0) -> float:
        """Run ``sim_seconds`` and return simulated time / wall time."""
        t0 = time.perf_counter()
        self.run_for(sim_seconds)
        return sim_seconds / max(time.perf_counter() - t0, 1e-9)

    # ------------------------------------------------------------------ state
    def snapshot(self) -> SimSnapshot:
        """Consistent copy of time, qpos and qvel (taken under the physics lock)."""
        with self._lock:
            return SimSnapshot(float(self.data.time), self.data.qpos.copy(), self.data.qvel.copy())

    def joint_positions(self) -> dict[str, float]:
        with self._lock:
            q = self.data.qpos[self.world.joint_qpos_adr].copy()
        return dict(zip(G1_JOINT_NAMES, q.tolist()))

    def joint_velocities(self) -> dict[str, float]:
        with self._lock:
            v = self.data.qvel[self.world.joint_dof_adr].copy()
        return dict(zip(G1_JOINT_NAMES, v.tolist()))

    def joint_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(positions, velocities, last applied torques), each (29,) in G1_JOINT_NAMES order."""
        with self._lock:
            return (self.data.qpos[self.world.joint_qpos_adr].copy(), self.data.qvel[self.world.joint_dof_adr].copy(),
                    np.array(self.last_torques, dtype=float))  # fmt: skip

    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Pelvis (position, quaternion (w,x,y,z)) in the world."""
        with self._lock:
            q = self.data.qpos[self._base_q : self._base_q + 7].copy()
        return q[0:3], q[3:7] / np.linalg.norm(q[3:7])

    def base_twist(self) -> tuple[np.ndarray, np.ndarray]:
        """Pelvis (linear, angular) velocity, both in the world frame."""
        with self._lock:
            q = self.data.qpos[self._base_q + 3 : self._base_q + 7].copy()
            v = self.data.qvel[self._base_v : self._base_v + 6].copy()
        return v[0:3], frames.quat_to_matrix(q) @ v[3:6]

    def robot_qpos(self) -> np.ndarray:
        """The G1's 36-D MuJoCo configuration [p, quat(w,x,y,z), 29 joints]."""
        with self._lock:
            return self.data.qpos[self._base_q : self._base_q + 36].copy()

    def object_pose(self, object_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Object frame (position, quaternion (w,x,y,z)) in the world."""
        s = self.object_state(object_id)
        return s.pos, s.quat

    def object_twist(self, object_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Object frame origin (linear, angular) velocity in the world frame."""
        s = self.object_state(object_id)
        return s.linvel, s.angvel

    def object_state(self, object_id: str) -> ObjectState:
        info = self._object_info(object_id)
        bid = self._obj_body[object_id]
        m, d = self.model, self.data
        with self._lock:
            if info.movable:
                j = m.body_jntadr[bid]
                qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
                pos = d.qpos[qa : qa + 3].copy()
                quat = d.qpos[qa + 3 : qa + 7].copy()
                quat /= np.linalg.norm(quat)
                lin = d.qvel[va : va + 3].copy()
                ang = frames.quat_to_matrix(quat) @ d.qvel[va + 3 : va + 6]
            else:
                pos, quat = info.initial_pos.copy(), info.initial_quat.copy()
                lin, ang = np.zeros(3), np.zeros(3)
        return ObjectState(info.id, info.object_class, info.movable, pos, quat, lin, ang, info.mass, info.com,
                           info.inertia, info.primitives)  # fmt: skip

    def scene_objects(self) -> list[ObjectState]:
        """All scenario objects with their description and current state."""
        return [self.object_state(oid) for oid in self.world.objects]

    def _object_info(self, object_id: str) -> ObjectInfo:
        try:
            return self.world.objects[object_id]
        except KeyError:
            raise SimulationError(f"unknown object id {object_id!r}; known: {', '.join(self.world.objects)}") from None

    def site_position(self, site_name: str) -> np.ndarray:
        """World position of a site at the current state (runs kinematics on a scratch copy)."""
        with self._lock:  # model and state of one world (a reset may rebuild both)
            model, q = self.model, self.data.qpos.copy()
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name)
        if sid < 0:
            raise SimulationError(f"unknown site {site_name!r}")
        scratch = mujoco.MjData(model)
        scratch.qpos[:] = q
        mujoco.mj_kinematics(model, scratch)
        return scratch.site_xpos[sid].copy()

    def has_fallen(self) -> bool:
        """True when the pelvis is low (absolute or above the feet) or the pelvis/torso tilts too much."""
        c = self.fall_criteria
        with self._lock:  # model, state and body ids of one world (a reset may rebuild them; the status
            # timer calls this during resets)
            model, q = self.model, self.data.qpos.copy()
            pelvis, torso, foot_sites = self._pelvis, self._torso, list(self._foot_sites)
        scratch = mujoco.MjData(model)
        scratch.qpos[:] = q
        mujoco.mj_kinematics(model, scratch)
        pz = scratch.xpos[pelvis][2]
        feet_z = min(scratch.site_xpos[s][2] for s in foot_sites)
        tilt = max(frames.tilt_angle(scratch.xquat[pelvis]), frames.tilt_angle(scratch.xquat[torso]))
        return bool(pz < c.min_pelvis_height or pz - feet_z < c.min_pelvis_above_feet or tilt > c.max_tilt)

    def pelvis_height(self) -> float:
        return float(self.base_pose()[0][2])


def make_simulation(name: str = "s1_basket", overrides: Mapping[str, object] | None = None, **kwargs) -> Simulation:
    """Convenience: Simulation(load_scenario(name, overrides))."""
    return Simulation(load_scenario(name, overrides), **kwargs)


ControllerFn = Callable[[mujoco.MjData], np.ndarray]
