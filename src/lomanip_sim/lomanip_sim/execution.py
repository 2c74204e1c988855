"""Execute a whole-body trajectory on a Simulation: checks, controller hand-over, logs, metrics.

Why: the sim node's Execute action, the benchmark and the tests share one procedure:

1. check the plan before anything moves (structure was checked when the Trajectory was built; here:
   objects exist in the world, the first point is near the robot's current state);
2. hand the robot to the :class:`~lomanip_sim.wbc.WholeBodyController` (the executor wraps it as the
   Simulation's controller, so it runs inside every physics step at 500 Hz);
3. log tracking errors, planned vs measured contact forces and the robot/object configuration (for
   the video) at ``log_rate``; detect a fall;
4. after the plan plus ``settle_time`` of holding its final point, measure metrics and task success.

The WBC keeps holding the final point afterwards. :meth:`Execution.stop` (cancel, fall, error)
hands the robot back to the standing controller, holding its current joint positions.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import mujoco
import numpy as np

from . import frames
from .contact_forces import contact_force_totals
from .robot_model import FOOT_BODIES, FOOT_SITES, HAND_BODIES, TORSO_BODY
from .standing import StandingController
from .task_success import evaluate
from .trajectory import LIMBS, EXECUTION_FAILED, StartTolerance, Trajectory, TrajectoryError, check_against_scene, check_start
from .wbc import WbcGains, WholeBodyController


@dataclass
class ExecutionOptions:
    settle_time: float = 1.0  # s of holding the final point before success is measured
    log_rate: float = 50.0  # Hz, logs and video frames
    start_tolerance: StartTolerance = field(default_factory=StartTolerance)


@dataclass
class ExecutionMetrics:
    """Mirror of lomanip_msgs/ExecutionMetrics (plus controller statistics)."""

    task_success: bool = False
    task_success_detail: str = ""
    fell: bool = False
    duration: float = 0.0  # s simulated (plan + settle)
    real_time_factor: float = 0.0  # simulated time / wall time of physics + control
    max_base_position_error: float = 0.0
    rms_base_position_error: float = 0.0
    max_joint_error: float = 0.0
    rms_joint_error: float = 0.0
    final_object_position_error: float = 0.0
    final_object_yaw_error: float = 0.0
    final_object_tilt_error: float = 0.0  # rad, angle between actual and planned object z axes (not in the msg)
    qp_failures: int = 0
    cancelled: bool = False
    #: N, the largest total contact force on one robot link other than the feet and the hands (an elbow
    #: on the carried box, a knee on the floor), sampled at the log rate, and that link and what it
    #: touched (not in the msg). The plan has no such contacts: this is physics the plan did not
    #: expect (docs/execution.md, session 40: S1's elbows and wrists press on the box with up to 140 N)
    max_unplanned_contact_force: float = 0.0
    unplanned_contact: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class ExecutionLog:
    t: list = field(default_factory=list)
    base_error: list = field(default_factory=list)
    joint_rms: list = field(default_factory=list)
    joint_max: list = field(default_factory=list)
    qpos: list = field(default_factory=list)  # full-world qpos (for rendering the run afterwards)
    measured: dict = field(default_factory=lambda: {l: [] for l in LIMBS})
    planned: dict = field(default_factory=lambda: {l: [] for l in LIMBS})


class Execution:
    """One execution of ``traj`` on ``sim`` (a lomanip_sim.simulator.Simulation)."""

    def __init__(self, sim, traj: Trajectory, gains: WbcGains | None = None, options: ExecutionOptions | None = None):
        self.sim, self.traj = sim, traj
        self.opt = options or ExecutionOptions()
        check_against_scene(traj, sim.world.objects)
        check_start(traj, sim.robot_qpos(), self.opt.start_tolerance)
        self.wbc = WholeBodyController(sim.world, traj, gains)
        self.log = ExecutionLog()
        self.initial_objects = {oid: sim.object_pose(oid) for oid in sim.world.objects}
        m = sim.model
        self._torso = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, TORSO_BODY)
        self._feet = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for s in FOOT_SITES.values()]
        self._plan_pose = self._planned_fall_measures()
        root = m.body_rootid[self.wbc.pelvis]
        planned = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in (*FOOT_BODIES.values(), *HAND_BODIES.values())}
        #: robot bodies whose contacts the plan never has (all but the feet and the hands)
        self._unplanned_bodies = {b for b in range(m.nbody) if m.body_rootid[b] == root and b not in planned}
        self._max_unplanned = (0.0, "")
        self._contacts_due = False
        self._log_every = max(1, int(round(1.0 / (self.opt.log_rate * sim.timestep))))
        self._steps = 0
        self._e2_base = self._e2_joint = 0.0
        self._n_err = 0
        self._max_base = self._max_joint = 0.0
        self.fell = False
        self.started = self.finished = False
        self._wall0 = self._wall_total = 0.0
        self._last_wall = None
        self.metrics: ExecutionMetrics | None = None

    # ----------------------------------------------------------------- TorqueController protocol
    def reset(self, data: mujoco.MjData) -> None:
        self.wbc.reset(data)

    def observe(self, data: mujoco.MjData) -> None:
        self.wbc.observe(data)
        if self._contacts_due:  # (after mj_step2: the contact list and its forces are of one step)
            self._contacts_due = False
            self._unplanned_contacts(data)

    def compute(self, data: mujoco.MjData) -> np.ndarray:
        now = time.perf_counter()
        if self._last_wall is not None:
            self._wall_total += now - self._last_wall  # wall time inside physics+control, pacing sleeps excluded below
        self._last_wall = now
        tau = self.wbc.compute(data)
        st = self.wbc.status
        if st.t_ref <= self.traj.duration + 1e-9:
            self._n_err += 1
            self._e2_base += st.base_position_error**2
            self._e2_joint += st.joint_error_rms**2
            self._max_base = max(self._max_base, st.base_position_error)
            self._max_joint = max(self._max_joint, st.joint_error_max)
        if self._steps % self._log_every == 0:
            self._log(data, st)
            self.fell = self.fell or self._fallen(data)
        self._steps += 1
        return tau

    # -----------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.wbc.status.t_ref

    @property
    def progress(self) -> float:
        return float(min(max(self.time / self.traj.duration, 0.0), 1.0))

    @property
    def done(self) -> bool:
        return self.fell or self.time >= self.traj.duration + self.opt.settle_time

    def start(self) -> None:
        """Hand the robot to the whole-body controller (trajectory time 0 = now)."""
        self.sim.set_controller(self)
        self.started = True
        self._wall0 = time.perf_counter()

    def pause_wall_clock(self) -> None:
        """Called by a paced runner before it sleeps, so RTF counts physics + control time only."""
        self._last_wall = None

    def stop(self) -> None:
        """Safe stop: the standing controller takes over, holding the current joint positions."""
        q = self.sim.joint_arrays()[0]
        stand = StandingController(self.sim.model, self.sim.world.joint_qpos_adr, self.sim.world.joint_dof_adr,
                                   self.sim.world.torque_limits, q_des=q)  # fmt: skip
        self.sim.set_controller(stand)

    def finish(self, cancelled: bool = False) -> ExecutionMetrics:
        """Metrics and task success from the current physics state."""
        sim, tr = self.sim, self.traj
        outcome = evaluate(sim, tr, self.initial_objects, self.fell)
        e_pos, e_yaw, e_tilt = 0.0, 0.0, 0.0
        for oid, (p, q) in tr.objects.items():
            if oid in sim.world.objects and sim.world.objects[oid].movable:
                pa, qa = sim.object_pose(oid)
                b = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, sim.world.objects[oid].body_name)
                if b >= 0:  # the plan's pose is the object's CoM frame (the TO's), not the body origin
                    pa = pa + frames.quat_to_matrix(qa) @ self.wbc._com_offset(b)
                e_pos = max(e_pos, float(np.linalg.norm(pa - p[-1])))
                dy = frames.quat_to_yaw(qa) - frames.quat_to_yaw(q[-1])
                e_yaw = max(e_yaw, abs(math.atan2(math.sin(dy), math.cos(dy))))
                za, zp = frames.quat_to_matrix(qa)[:, 2], frames.quat_to_matrix(q[-1])[:, 2]
                e_tilt = max(e_tilt, float(np.arccos(np.clip(za @ zp, -1.0, 1.0))))
        n = max(self._n_err, 1)
        wall = self._wall_total if self._wall_total > 0 else time.perf_counter() - self._wall0
        simulated = self._steps * sim.timestep
        self.metrics = ExecutionMetrics(
            task_success=bool(outcome.success and not cancelled), task_success_detail=outcome.detail,
            fell=bool(self.fell), duration=simulated, real_time_factor=simulated / max(wall, 1e-9),
            max_base_position_error=self._max_base, rms_base_position_error=math.sqrt(self._e2_base / n),
            max_joint_error=self._max_joint, rms_joint_error=math.sqrt(self._e2_joint / n),
            final_object_position_error=e_pos, final_object_yaw_error=e_yaw, final_object_tilt_error=e_tilt,
            qp_failures=self.wbc.status.qp_failures, cancelled=cancelled,
            max_unplanned_contact_force=self._max_unplanned[0], unplanned_contact=self._max_unplanned[1])  # fmt: skip
        self.finished = True
        return self.metrics

    def run(self, on_feedback=None, should_cancel=None) -> ExecutionMetrics:
        """Run to completion as fast as possible (benchmarks, tests); returns the metrics."""
        self.start()
        chunk = max(1, int(round(0.02 / self.sim.timestep)))
        while not self.done:
            if should_cancel is not None and should_cancel():
                self.stop()
                return self.finish(cancelled=True)
            self.sim.step(chunk)
            if on_feedback is not None:
                on_feedback(self)
        metrics = self.finish()
        if self.fell:
            self.stop()
        return metrics

    # -----------------------------------------------------------------
    def _log(self, data: mujoco.MjData, st) -> None:
        lg, tr = self.log, self.traj
        lg.t.append(st.t_ref)
        lg.base_error.append(st.base_position_error)
        lg.joint_rms.append(st.joint_error_rms)
        lg.joint_max.append(st.joint_error_max)
        lg.qpos.append(data.qpos.copy())
        # measured after this step's mj_step2 (observe): here, after mj_step1, the contact list is
        # new but efc_force still holds the last step's constraint forces, so mj_contactForce read
        # other constraints' rows (the "unplanned contacts" of 7988 N and 11984 N before session 44)
        self._contacts_due = True
        meas = self.wbc.measured_forces  # of the last completed step (read after its mj_step2)
        i, s = tr.index_at(st.t_ref)
        for limb in LIMBS:
            lg.measured[limb].append(meas[limb])
            if limb in tr.forces and st.t_ref <= tr.duration:
                f = tr.forces[limb]
                lg.planned[limb].append(f[i] + s * (f[i + 1] - f[i]))
            else:
                lg.planned[limb].append(lg.planned[limb][-1] if lg.planned[limb] else np.zeros(3))

    def _unplanned_contacts(self, data: mujoco.MjData) -> None:
        """Track the largest total contact force on one robot link the plan has no contact for."""
        m, watched = self.sim.model, self._unplanned_bodies

        def key(b1: int, b2: int):
            for mine, other in ((b1, b2), (b2, b1)):
                if mine in watched and other not in watched and m.body_rootid[other] != m.body_rootid[mine]:
                    return mine, int(m.body_rootid[other])
            return None

        for (mine, other), f in contact_force_totals(m, data, key).items():
            n = float(np.linalg.norm(f))
            if n > self._max_unplanned[0]:
                what = "floor" if other == 0 else m.body(int(other)).name
                self._max_unplanned = (n, f"{m.body(mine).name} on {what} at t={float(data.time) - self.wbc.t0:.2f} s")

    def _measures(self, data: mujoco.MjData) -> tuple[float, float, float]:
        """Pelvis height, pelvis height above the lowest foot site, max pelvis/torso tilt."""
        pz = float(data.xpos[self.wbc.pelvis][2])
        feet_z = min(data.site_xpos[s][2] for s in self._feet)
        tilt = max(frames.tilt_angle(data.xquat[self.wbc.pelvis]), frames.tilt_angle(data.xquat[self._torso]))
        return pz, pz - feet_z, float(tilt)

    def _planned_fall_measures(self) -> np.ndarray:
        """(N,3) the fall measures of the plan's own configurations (so a planned squat is no fall)."""
        m, tr, w = self.sim.model, self.traj, self.wbc
        d = mujoco.MjData(m)
        d.qpos[:] = self.sim.data.qpos
        out = np.zeros((tr.n, 3))
        for i in range(tr.n):
            d.qpos[w.bq : w.bq + tr.qpos(i).size] = tr.qpos(i)
            mujoco.mj_kinematics(m, d)
            out[i] = self._measures(d)
        return out

    def _fallen(self, data: mujoco.MjData) -> bool:
        """Fixed fall thresholds, relaxed to the plan's own pose minus a margin where the plan goes past them."""
        c = self.sim.fall_criteria
        pz, above, tilt = self._measures(data)
        i, _s = self.traj.index_at(min(self.time, self.traj.duration))
        plan = self._plan_pose[i : i + 2]
        min_pz = min(c.min_pelvis_height, plan[:, 0].min() - c.plan_height_margin)
        min_above = min(c.min_pelvis_above_feet, plan[:, 1].min() - c.plan_height_margin)
        max_tilt = max(c.max_tilt, plan[:, 2].max() + c.plan_tilt_margin)
        return bool(pz < min_pz or above < min_above or tilt > max_tilt)


def execution_error(exc: Exception) -> TrajectoryError:
    """Any unexpected failure while setting up an execution, as a coded error."""
    if isinstance(exc, TrajectoryError):
        return exc
    return TrajectoryError(EXECUTION_FAILED, f"execution could not start: {exc}")
