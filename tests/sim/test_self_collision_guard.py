"""self_collision_guard: barrier rows that keep the pelvis off the G1's hip links and the hands off the legs, alone and in the QP."""

import mujoco
import numpy as np
import pytest
from to_cases import simulation

from lomanip_sim.robot_model import G1_JOINT_NAMES
from lomanip_sim.trajectory import LimbContact, Phase
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


def _stand_before_a_box(gap: float):
    """case_stand's plan in a world with a free 20 cm box ``gap`` m in front of the right hand box."""
    from lomanip_sim import scene_world
    from lomanip_sim.simulator import Simulation

    sim, tr = simulation("case_stand")
    m, d = sim.model, sim.data
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "right_hand_collision")
    mujoco.mj_forward(m, d)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = d.geom_xpos[g] + (signs * m.geom_size[g]) @ d.geom_xmat[g].reshape(3, 3).T
    front = corners[:, 0].max()
    box = scene_world.SceneObjectSpec("box", "box", True, (front + gap + 0.1, float(d.geom_xpos[g][1]), float(d.geom_xpos[g][2])),
                                      (1.0, 0.0, 0.0, 0.0), 1.0, (scene_world.ScenePrimitive("box", (0.2, 0.2, 0.2)),))
    world = scene_world.build_scene_world([box], robot_qpos=tr.qpos(0))
    return Simulation(world), tr


def test_qp_keeps_a_free_hand_off_a_movable_object():
    """A plan whose right arm reaches 0.12 rad further forward, into a box the robot's hand box is
    5 mm from: with the object rows the QP's accelerations obey the barrier, with the hand's own
    arm alone (the row has no other columns); with ``guard_hand_objects`` off the hand task drives
    the hand into the box."""
    sim, tr = _stand_before_a_box(0.005)
    j = G1_JOINT_NAMES.index("right_shoulder_pitch_joint")
    tr.q[..., j] = tr.q[..., j] - 0.12   # forward
    mujoco.mj_forward(sim.model, sim.data)
    guarded = WholeBodyController(sim.world, tr, WbcGains())
    guarded.compute(sim.data)
    rows = {r.pair: r for r in guarded.guard_rows}
    pair = ("right_wrist_yaw_link", "box")
    assert pair in rows and 0.003 < rows[pair].distance < 0.007
    r = rows[pair]
    assert r.row @ guarded.last_qdd >= r.lower - 1e-6
    arm = [i + 6 for i, n in enumerate(G1_JOINT_NAMES) if n.startswith("right_")
           and any(k in n for k in ("shoulder", "elbow", "wrist"))]
    assert np.all(np.delete(r.row, arm) == 0.0) and np.any(r.row[arm] != 0.0)
    free = WholeBodyController(sim.world, tr, WbcGains(guard_hand_objects=False))
    free.compute(sim.data)
    assert pair not in {g.pair for g in free.guard_rows}
    assert r.row @ free.last_qdd < r.lower - 1.0


def test_object_rows_are_off_in_and_just_after_a_hand_contact():
    """The hand's object rows are off while the plan has it in contact, and for
    ``guard_object_release`` s after."""
    sim, tr = _stand_before_a_box(0.005)
    w = WholeBodyController(sim.world, tr, WbcGains())
    assert w._object_free["right_hand"].all()   # case_stand: no hand contact
    ph = tr.phases[0]
    hold = LimbContact("box", np.zeros(3), np.array([-1.0, 0.0, 0.0]))
    w.traj.phases = [Phase(0.0, 0.3, ph.contacts), Phase(0.3, 0.6, {**ph.contacts, "right_hand": hold}),
                     Phase(0.6, tr.t[-1], ph.contacts)]
    free = w._free_of_objects("right_hand")
    t = tr.t
    assert free[t < 0.3].all() and free[t > 0.6 + w.g.guard_object_release].all()
    assert not free[(t >= 0.3) & (t <= 0.6 + w.g.guard_object_release)].any()
    assert w._free_of_objects("left_hand").all()


def test_exec_trace_prints_the_active_guard_rows():
    """tools/exec_trace.py --guard: a line names each active pair with its distance."""
    import importlib.util
    from pathlib import Path

    from lomanip_sim.execution import Execution

    path = Path(__file__).resolve().parents[2] / "tools" / "exec_trace.py"
    spec = importlib.util.spec_from_file_location("exec_trace_under_test", path)
    exec_trace = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(exec_trace)
    sim, tr = _stand_before_a_box(0.005)
    ex = Execution(sim, tr)
    ex.start()
    sim.step(5)
    line = exec_trace.trace_line(ex, [], guard=True)
    assert "guard [right_wrist_yaw_link / box 0." in line
    assert "guard" not in exec_trace.trace_line(ex, [])
