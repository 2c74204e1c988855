"""Closed-loop standing / balance controller for the torque-controlled G1 (runs every physics step).

Why: the G1's servos are converted to torque motors in world.py, so something must hold it up
between (and before) whole-body trajectories, and the sim must not cheat (no frozen base, no weld,
no qpos writes). The law is a classic contact-force-distribution balance controller:

1. a desired generalized force on the floating base = bias forces (gravity + Coriolis, from
   ``qfrc_bias``) + CoM PD toward the centre of the support polygon (horizontal) + pelvis
   orientation PD;
2. both feet's 6-D wrenches are chosen (weighted least norm, foot moments penalised so the load
   goes through forces) to produce that base force through the contact Jacobians;
3. joint torques = joint bias forces - J_c,joints^T f (quasi-static gravity/contact compensation)
   + joint PD toward the stand posture; clipped to the G1 torque limits.

Step (3) is the ankle/hip strategy in one formula: a CoM error tilts the foot wrenches, which the
legs realise as ankle and hip torques. Use it after ``mj_step1`` (or ``mj_forward``) so kinematics
and ``qfrc_bias`` belong to the current state.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import math

import mujoco
import numpy as np

from . import frames
from .robot_model import FOOT_SITES, G1_JOINT_NAMES, PELVIS_BODY


class ControllerError(RuntimeError):
    """The controller was configured inconsistently with the model."""


def _default_kp() -> np.ndarray:
    kp = np.empty(29)
    kp[0:12] = [250, 250, 200, 250, 120, 80] * 2  # legs: hip pitch/roll/yaw, knee, ankle pitch/roll
    kp[12:15] = [200, 200, 200]  # waist
    kp[15:29] = [60, 60, 40, 40, 20, 8, 8] * 2  # arms
    return kp


def _default_kd() -> np.ndarray:
    kd = np.empty(29)
    kd[0:12] = [6, 6, 4, 6, 3, 2] * 2
    kd[12:15] = [5, 5, 5]
    kd[15:29] = [2, 2, 1.5, 1.5, 0.5, 0.3, 0.3] * 2
    return kd


@dataclass
class StandingGains:
    """Gains of :class:`StandingController` (SI units, per-joint arrays in G1_JOINT_NAMES order).

    Tuned by a push sweep in S1 (0.2 s pelvis pushes, 20 N steps; see tests/sim/test_standing.py):
    survives forward 200 N, backward 60 N (the heel is only 5.5 cm behind the ankle), sideways 100 N.
    Lower pelvis-orientation gains let the hips help (forward limit 80 N -> 200 N).
    """

    kp: np.ndarray = field(default_factory=_default_kp)  # N m / rad
    kd: np.ndarray = field(default_factory=_default_kd)  # N m s / rad
    com_kp: float = 40.0  # 1/s^2 (times robot mass -> N/m)
    com_kd: float = 20.0  # 1/s
    ori_kp: float = 100.0  # N m / rad, pelvis roll/pitch/yaw
    ori_kd: float = 10.0  # N m s / rad
    com_forward_offset: float = 0.035  # m, CoM target ahead of the ankle midpoint (foot centre side)
    foot_torque_weight: float = 30.0  # penalty of foot moments vs forces in the distribution


class StandingController:
    """Computes G1 joint torques that keep it standing at ``q_des`` (default: stand keyframe)."""

    def __init__(self, model: mujoco.MjModel, joint_qpos_adr, joint_dof_adr, torque_limits,
                 q_des: np.ndarray | None = None, gains: StandingGains | None = None):  # fmt: skip
        self.model = model
        self.qadr = np.asarray(joint_qpos_adr)
        self.dadr = np.asarray(joint_dof_adr)
        if len(self.qadr) != len(G1_JOINT_NAMES):
            raise ControllerError("need one qpos/dof address per G1 joint")
        self.limits = np.asarray(torque_limits, dtype=float)
        self.gains = gains or StandingGains()
        self.q_des = np.array(q_des, dtype=float) if q_des is not None else None
        self.pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, PELVIS_BODY)
        self.sites = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in FOOT_SITES.values()]
        if self.pelvis < 0 or min(self.sites) < 0:
            raise ControllerError("pelvis body or foot sites missing from the model")
        fj = model.body_jntadr[self.pelvis]
        self.base_dof = int(model.jnt_dofadr[fj])
        self.mass = float(model.body_subtreemass[self.pelvis])
        self.robot_dofs = np.concatenate([np.arange(self.base_dof, self.base_dof + 6), self.dadr])
        nv = model.nv
        self._jp = np.zeros((3, nv))
        self._jr = np.zeros((3, nv))
        self._jc = np.zeros((12, nv))
        self._jcom = np.zeros((3, nv))
        w = np.ones(12)
        w[3:6] = w[9:12] = self.gains.foot_torque_weight
        self._winv = 1.0 / w
        self.yaw_ref = 0.0
        self._R_des_T = np.eye(3)
        self.last_foot_wrenches = np.zeros(12)

    def reset(self, data: mujoco.MjData) -> None:
        """Latch the heading to hold (current pelvis yaw) and the posture (stand) target."""
        fj = self.model.body_jntadr[self.pelvis]
        qa = self.model.jnt_qposadr[fj]
        self.yaw_ref = frames.quat_to_yaw(data.qpos[qa + 3 : qa + 7])
        self._R_des_T = frames.quat_to_matrix(frames.yaw_to_quat(self.yaw_ref)).T
        if self.q_des is None:
            from .robot_model import G1_STAND_QPOS

            self.q_des = G1_STAND_QPOS[7:].copy()

    def compute(self, data: mujoco.MjData) -> np.ndarray:
        """Joint torques (29,) for the current state; kinematics and qfrc_bias must be current."""
        m, g = self.model, self.gains
        if self.q_des is None:
            self.reset(data)
        b0 = self.base_dof
        # Contact Jacobians of both foot sites (world-frame force/torque at the site).
        for i, sid in enumerate(self.sites):
            mujoco.mj_jacSite(m, data, self._jp, self._jr, sid)
            self._jc[6 * i : 6 * i + 3] = self._jp
            self._jc[6 * i + 3 : 6 * i + 6] = self._jr
        mujoco.mj_jacSubtreeCom(m, data, self._jcom, self.pelvis)
        qvel = data.qvel
        com = data.subtree_com[self.pelvis]
        vcom = self._jcom @ qvel

        # CoM target: midpoint of the feet, shifted towards the toes (foot centre).
        p_l, p_r = data.site_xpos[self.sites[0]], data.site_xpos[self.sites[1]]
        R_l = data.site_xmat[self.sites[0]].reshape(3, 3)
        R_r = data.site_xmat[self.sites[1]].reshape(3, 3)
        fwd = R_l[:, 0] + R_r[:, 0]
        fwd[2] = 0.0
        fwd /= max(math.hypot(fwd[0], fwd[1]), 1e-9)
        target = 0.5 * (p_l + p_r) + g.com_forward_offset * fwd
        F = np.zeros(3)
        F[0:2] = self.mass * (g.com_kp * (target[0:2] - com[0:2]) - g.com_kd * vcom[0:2])

        # Pelvis orientation PD (roll, pitch to zero; yaw to the latched heading), world frame.
        R = data.xmat[self.pelvis].reshape(3, 3)
        E = self._R_des_T @ R
        err_local = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
        omega_local = qvel[b0 + 3 : b0 + 6]  # free joint: angular velocity in the body frame
        tau_local = -g.ori_kp * err_local - g.ori_kd * omega_local
        # Base generalized force: world force at the pelvis origin + body-frame torque about it.
        p_pelvis = data.xpos[self.pelvis]
        r = com - p_pelvis
        torque_world_at_origin = np.array([r[1] * F[2] - r[2] * F[1], r[2] * F[0] - r[0] * F[2], r[0] * F[1] - r[1] * F[0]])
        W = np.concatenate([F, R.T @ torque_world_at_origin + tau_local])

        h = data.qfrc_bias
        b = h[b0 : b0 + 6] + W
        A = self._jc[:, b0 : b0 + 6].T  # (6, 12)
        AW = A * self._winv
        try:
            f = self._winv * (A.T @ np.linalg.solve(AW @ A.T, b))
        except np.linalg.LinAlgError:
            f = np.zeros(12)
        self.last_foot_wrenches = f

        q = data.qpos[self.qadr]
        qd = qvel[self.dadr]
        Jcj = self._jc[:, self.dadr]
        tau = h[self.dadr] - Jcj.T @ f + g.kp * (self.q_des - q) - g.kd * qd
        return np.clip(tau, -self.limits, self.limits)
