"""self_collision_guard: barrier rows that keep the pelvis off the G1's hip links and the hands off the legs, alone and in the QP."""

import mujoco
import numpy as np
import pytest
from to_cases import simulation

from lomanip_sim.robot_model import G1_JOINT_NAMES
from lomanip_sim.self_collision_guard import HAND_LEG_PAIRS, HIP_PAIRS, SelfCollisionGuard
from lomanip_sim.wbc import WbcGains, WholeBodyController

PAIR = ("pelvis", "right_hip_roll_link")


def _squat_hip(sim, roll: float, roll_rate: float = 0.0) -> None:
    """The robot as it stands, its right hip pitched to -2.0 rad (a deep squat's) at ``roll``."""
    m, d = sim.model, sim.data
    adr = sim.world.joint_qpos_adr
    d.qpos[adr[G1_JOINT_NAMES.index("right_hip_pitch_joint")]] = -2.0
    d.qpos[adr[G1_JOINT_NAMES.index("right_hip_roll_joint")]] = roll
    d.qvel[:] = 0.0
    d.qvel[sim.world.joint_dof_adr[G1_JOINT_NAMES.index("right_hip_roll_joint")]] = roll_rate
    mujoco.mj_forward(m, d)


def _dofs(sim) -> slice:
    start = sim.world.joint_dof_adr[0] - 6
    return slice(start, start + 35)


def _geoms(guard, pair):
    return next(g for p, _a, _b, g in guard.pairs if p == pair)


def test_every_hip_pair_is_found_on_the_model():
    sim, _tr = simulation("case_stand")
    guard = SelfCollisionGuard(sim.model)
    assert [p for p, *_ in guard.pairs] == list(HIP_PAIRS)
    with pytest.raises(ValueError, match="no body 'nope'"):
        SelfCollisionGuard(sim.model, pairs=[("pelvis", "nope")])


@pytest.mark.parametrize("roll", [0.0, 0.05, 0.15])   # apart, then the link 0.5 and 3 mm into the pelvis
def test_row_gives_the_distance_rate(roll):
    """The row times the velocity is the distance's rate (finite differences), whether the links
    are apart or overlap (MuJoCo's closest points swap sides when they overlap)."""
    sim, _tr = simulation("case_stand")
    m, d = sim.model, sim.data
    guard = SelfCollisionGuard(m, activation=0.1)
    _squat_hip(sim, roll)
    d.qvel[_dofs(sim)] = np.random.default_rng(3).normal(size=35) * 0.3
    mujoco.mj_forward(m, d)
    row = next(r for r in guard.rows(d, _dofs(sim)) if r.pair == PAIR)
    h = 1e-5
    d2 = mujoco.MjData(m)
    d2.qpos[:], d2.qvel[:] = d.qpos, d.qvel
    mujoco.mj_integratePos(m, d2.qpos, d2.qvel, h)
    mujoco.mj_forward(m, d2)
    moved, _pa, _pb = guard.closest(d2, _geoms(guard, PAIR))
    assert (row.distance > 0) == (roll == 0.0)
    assert row.row @ d.qvel[_dofs(sim)] == pytest.approx((moved - row.distance) / h, rel=1e-3, abs=1e-6)


def test_qp_decelerates_a_hip_closing_on_the_pelvis():
    """A hip rolling into the pelvis 0.4 mm away: the guarded QP's accelerations obey the barrier
    row (they turn the closing round); the same QP without the guard (a stiff posture task here)
    lets the link run on into the pelvis."""
    import dataclasses

    sim, tr = simulation("case_stand")
    _squat_hip(sim, roll=0.0, roll_rate=1.0)
    gains = WbcGains(posture_kp=400.0, w_posture=10.0)
    guarded = WholeBodyController(sim.world, tr, gains)
    guarded.compute(sim.data)
    rows = {r.pair: r for r in guarded.guard_rows}
    assert PAIR in rows and 0.0 < rows[PAIR].distance < 0.002
    r = rows[PAIR]
    assert r.row @ sim.data.qvel[_dofs(sim)] < 0.0 and r.lower > 0.0   # closing: the gap must open
    assert r.row @ guarded.last_qdd >= r.lower - 1e-6
    free = WholeBodyController(sim.world, tr, dataclasses.replace(gains, guard_rate=0.0))
    free.compute(sim.data)
    assert free.guard_rows == []
    assert r.row @ free.last_qdd < 0.0


HAND_PAIR = ("right_wrist_yaw_link", "right_hip_pitch_link")


def _arm(sim_or_q, roll: float, adr=None) -> None:
    """Set the right arm hanging with the elbow bent (1.2 rad), shoulder pitch 0.2 rad, at shoulder ``roll``."""
    for name, q in (("right_shoulder_roll_joint", roll), ("right_shoulder_pitch_joint", 0.2), ("right_elbow_joint", 1.2)):
        sim_or_q[..., adr[G1_JOINT_NAMES.index(name)] if adr is not None else G1_JOINT_NAMES.index(name)] = q


def test_every_hand_leg_pair_is_found_on_the_model():
    sim, _tr = simulation("case_stand")
    guard = SelfCollisionGuard(sim.model, HAND_LEG_PAIRS)
    assert [p for p, *_ in guard.pairs] == list(HAND_LEG_PAIRS)
    # the wrist-yaw link carries the sim's hand box and the wrist mesh: both are guarded
    assert all(len(geoms) == 2 for _p, _a, _b, geoms in guard.pairs)


def test_qp_keeps_a_hand_off_its_hip():
    """A plan that hangs the right hand 3.7 cm inside its hip (shoulder roll -0.05 rad) with the
    robot's hand 5 mm off it (-0.15 rad): with the hand pairs the QP's accelerations obey the
    barrier row; with ``guard_hands`` off the hand and posture tasks drive the hand into the hip."""
    sim, tr = simulation("case_stand")
    _arm(tr.q, -0.05)
    _arm(sim.data.qpos, -0.15, sim.world.joint_qpos_adr)
    sim.data.qvel[:] = 0.0
    mujoco.mj_forward(sim.model, sim.data)
    guarded = WholeBodyController(sim.world, tr, WbcGains())
    guarded.compute(sim.data)
    rows = {r.pair: r for r in guarded.guard_rows}
    assert HAND_PAIR in rows and 0.0 < rows[HAND_PAIR].distance < 0.006
    r = rows[HAND_PAIR]
    assert r.row @ guarded.last_qdd >= r.lower - 1e-6
    free = WholeBodyController(sim.world, tr, WbcGains(guard_hands=False))
    free.compute(sim.data)
    assert all(p in HIP_PAIRS for p in (g.pair for g in free.guard_rows))
    assert r.row @ free.last_qdd < r.lower
