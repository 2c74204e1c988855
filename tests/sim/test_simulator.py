"""simulator: named state access, object states, torque commands, pushes, reset, thread safety, and
the S2 trolley rolls when its handle is pushed but stays put otherwise."""

import threading

import numpy as np
import pytest

from lomanip_sim import frames
from lomanip_sim.robot_model import G1_JOINT_NAMES, G1_STAND_QPOS
from lomanip_sim.scenario import load_scenario
from lomanip_sim.simulator import Simulation, SimulationError


@pytest.fixture(scope="module")
def s2():
    return Simulation(load_scenario("s2_trolley"))


def test_state_access(s2):
    s2.reset()
    assert s2.time == 0.0
    q = s2.joint_positions()
    assert list(q) == list(G1_JOINT_NAMES)
    assert np.allclose(list(q.values()), G1_STAND_QPOS[7:])
    assert list(s2.joint_velocities()) == list(G1_JOINT_NAMES)
    pos, quat = s2.base_pose()
    assert pos[2] == pytest.approx(0.79) and np.allclose(quat, [1, 0, 0, 0])
    s2.step(50)
    assert s2.time == pytest.approx(0.1)
    lin, ang = s2.base_twist()
    assert lin.shape == (3,) and ang.shape == (3,)
    assert s2.robot_qpos().shape == (36,)


def test_scene_objects(s2):
    s2.reset()
    objs = {o.id: o for o in s2.scene_objects()}
    assert set(objs) == {"box", "table", "trolley"}
    box = objs["box"]
    assert box.object_class == "box" and box.movable and box.mass == pytest.approx(2.5)
    assert np.allclose(box.quat_xyzw, frames.wxyz_to_xyzw(box.quat))
    assert not objs["table"].movable and np.allclose(objs["table"].linvel, 0)
    with pytest.raises(SimulationError, match="unknown object id"):
        s2.object_pose("basket")


def test_torque_command_validation(s2):
    s2.reset()
    with pytest.raises(SimulationError):
        s2.step(1, torques=np.zeros(5))
    with pytest.raises(SimulationError):
        s2.step(1, torques={"not_a_joint": 1.0})
    s2.step(1, torques={"left_knee_joint": 1e6})  # clipped to the limit
    _, _, tau = s2.joint_arrays()
    assert tau[G1_JOINT_NAMES.index("left_knee_joint")] == pytest.approx(139.0)
    with pytest.raises(SimulationError):
        s2.apply_external_force("no_such_body", [1, 0, 0], 0.1)


def _handle_point(sim):
    tr = next(o for o in sim.scene_objects() if o.id == "trolley")
    h = next(p for p in tr.primitives if p.name == "trolley_handle")
    return frames.transform_point(tr.pos, tr.quat, h.pos)


def test_trolley_stays_put_without_force(s2):
    s2.reset()
    s2.run_for(0.5)
    p0, q0 = s2.object_pose("trolley")
    s2.run_for(2.0)
    p1, q1 = s2.object_pose("trolley")
    assert np.linalg.norm(p1 - p0) < 0.005
    assert abs(frames.quat_to_yaw(q1) - frames.quat_to_yaw(q0)) < 0.01


def test_trolley_rolls_when_handle_pushed(s2):
    s2.reset()
    s2.run_for(0.5)
    p0, q0 = s2.object_pose("trolley")
    yaw = frames.quat_to_yaw(q0)
    forward = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    s2.apply_external_force("trolley", 15.0 * forward, 2.0, point_world=_handle_point(s2))
    s2.run_for(2.0)
    p1, q1 = s2.object_pose("trolley")
    moved = float((p1 - p0) @ forward)
    print(f"\ntrolley moved {moved:.2f} m under 15 N on the handle for 2 s")
    assert moved > 0.3
    assert abs(float((p1 - p0) @ np.array([-forward[1], forward[0], 0]))) < 0.05  # little lateral drift
    lin, _ = s2.object_twist("trolley")
    assert lin @ forward > 0.1
    assert not s2.has_fallen()


def test_reset_with_new_params_and_push_expires():
    sim = Simulation(load_scenario("s1_basket"))
    sim.apply_external_force("pelvis", [30, 0, 0], 0.05)
    sim.run_for(0.1)
    assert not sim._pushes  # expired
    assert not np.any(sim.data.xfrc_applied)
    sim.reset(load_scenario("s1_basket", {"box_mass": 4.2, "box_yaw": 1.2}))
    assert sim.time == 0.0
    assert sim.object_state("box").mass == pytest.approx(4.2)
    assert frames.quat_to_yaw(sim.object_pose("box")[1]) == pytest.approx(1.2)


def test_snapshot_is_consistent_while_stepping():
    sim = Simulation(load_scenario("s1_basket"))
    stop = threading.Event()

    def physics():
        while not stop.is_set():
            sim.step(10)

    th = threading.Thread(target=physics)
    th.start()
    try:
        snaps = [sim.snapshot() for _ in range(50)]
    finally:
        stop.set()
        th.join()
    times = [s.time for s in snaps]
    assert times == sorted(times)
    assert all(s.qpos.shape == (sim.model.nq,) for s in snaps)
    assert np.all(np.isclose(np.array([np.linalg.norm(s.qpos[3:7]) for s in snaps]), 1.0, atol=1e-6))


def test_real_time_factor_helper():
    sim = Simulation(load_scenario("s1_basket"))
    rtf = sim.real_time_factor(0.5)
    print(f"\nreal-time factor over 0.5 s: {rtf:.1f}")
    assert rtf > 1.0


def test_controller_observes_each_step_after_its_dynamics(s2):
    """A controller with ``observe(data)`` gets it after every step's mj_step2, where MuJoCo's contact
    list and constraint forces belong to the same step (read after mj_step1 they mix two steps)."""
    from lomanip_sim.contact_forces import LimbForceMeter

    s2.reset()
    standing = s2.controller
    meter = LimbForceMeter(s2.model)

    class Observing:
        def __init__(self):
            self.seen = []

        def reset(self, data):
            standing.reset(data)

        def compute(self, data):
            return standing.compute(data)

        def observe(self, data):
            f = meter.measure(data)
            self.seen.append(f["left_foot"][2] + f["right_foot"][2])

    ctl = Observing()
    s2.set_controller(ctl)
    try:
        s2.step(500)
        assert len(ctl.seen) == 500
        weight = float(s2.model.body_subtreemass[s2.model.body("pelvis").id]) * 9.81
        assert np.mean(ctl.seen[-100:]) == pytest.approx(weight, rel=0.03)
        s2.step(10, torques=np.zeros(len(G1_JOINT_NAMES)))  # commanded torques: the controller is not asked
        assert len(ctl.seen) == 500
    finally:
        s2.set_controller(standing)
