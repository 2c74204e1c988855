"""task_success: the S1/S2/generic definitions read from the physics state.

The evaluator is a pure function of the state, so these tests pose the world directly (qpos written
by the TEST to create a known outcome, then mj_forward); the executor never does that.
"""

import mujoco
import numpy as np
import pytest

from lomanip_sim.robot_model import G1_JOINT_NAMES, G1_STAND_QPOS
from lomanip_sim.scenario import load_scenario
from lomanip_sim.simulator import Simulation
from lomanip_sim.task_success import evaluate
from lomanip_sim.trajectory import make_trajectory


def _plan(scenario, n=3, objects=None, base_end=None):
    t = np.linspace(0.0, 1.0, n)
    base = np.tile(G1_STAND_QPOS[:3], (n, 1))
    if base_end is not None:
        base[-1] = base_end
    return make_trajectory(t, G1_JOINT_NAMES, np.tile(G1_STAND_QPOS[7:], (n, 1)), None, base,
                           np.tile(G1_STAND_QPOS[3:7], (n, 1)), objects=objects, scenario=scenario)


def _free_qpos(sim, oid):
    m = sim.model
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, oid)
    return int(m.jnt_qposadr[m.body_jntadr[b]])


@pytest.fixture(scope="module")
def s1():
    return Simulation(load_scenario("s1_basket"))


@pytest.fixture(scope="module")
def s2():
    return Simulation(load_scenario("s2_trolley"))


def test_s1_fails_when_standing_on_the_floor(s1):
    s1.reset()
    initial = {oid: s1.object_pose(oid) for oid in s1.world.objects}
    out = evaluate(s1, _plan("s1_basket"), initial, fell=False)
    assert not out.success
    assert "basket lifted 0.0 cm" in out.detail and "left foot NOT on the box" in out.detail


def test_s1_success_basket_up_and_feet_on_box(s1):
    s1.reset()
    initial = {oid: s1.object_pose(oid) for oid in s1.world.objects}
    d = s1.data
    box_top = s1.object_pose("box")[0][2] + 0.15
    d.qpos[0:3] = [s1.object_pose("box")[0][0], 0.0, G1_STAND_QPOS[2] + box_top]
    a = _free_qpos(s1, "basket")
    d.qpos[a + 2] += 0.15
    mujoco.mj_forward(s1.model, d)
    out = evaluate(s1, _plan("s1_basket"), initial, fell=False)
    assert out.success, out.detail
    assert "basket lifted 15.0 cm" in out.detail
    assert not evaluate(s1, _plan("s1_basket"), initial, fell=True).success
    d.qpos[a + 2] -= 0.08  # 7 cm is not enough
    mujoco.mj_forward(s1.model, d)
    assert not evaluate(s1, _plan("s1_basket"), initial, fell=False).success


@pytest.mark.parametrize("moved, expect", [(0.30, True), (0.10, False)])
def test_s2_box_on_trolley_and_distance(s2, moved, expect):
    s2.reset()
    initial = {oid: s2.object_pose(oid) for oid in s2.world.objects}
    p0 = initial["trolley"][0]
    planned = np.array([p0, p0 + [0.15, 0, 0], p0 + [0.30, 0, 0]])
    quats = np.tile([1.0, 0, 0, 0], (3, 1))
    plan = _plan("s2_trolley", objects={"trolley": (planned, quats), "box": _box_to_deck(initial)})
    d = s2.data
    t, b = _free_qpos(s2, "trolley"), _free_qpos(s2, "box")
    d.qpos[t] += moved
    d.qpos[b : b + 3] = d.qpos[t : t + 3] + [0.0, 0.0, 0.35 + 0.125 + 0.005]
    mujoco.mj_forward(s2.model, d)
    out = evaluate(s2, plan, initial, fell=False)
    assert out.success is expect, out.detail
    assert f"trolley moved {moved:.2f} m forward, planned 0.30 m" in out.detail


def test_s2_fails_with_box_still_on_table(s2):
    s2.reset()
    initial = {oid: s2.object_pose(oid) for oid in s2.world.objects}
    p0 = initial["trolley"][0]
    plan = _plan("s2_trolley", objects={"trolley": (np.array([p0, p0, p0 + [0.3, 0, 0]]), np.tile([1.0, 0, 0, 0], (3, 1))),
                                        "box": _box_to_deck(initial)})
    out = evaluate(s2, plan, initial, fell=False)
    assert not out.success and "box NOT on the trolley" in out.detail


def _box_to_deck(initial):
    b0, t0 = initial["box"][0], initial["trolley"][0]
    return np.array([b0, b0 + [0, 0, 0.2], t0 + [0, 0, 0.48]]), np.tile([1.0, 0, 0, 0], (3, 1))


@pytest.mark.parametrize("box_shift, expect", [(0.0, True), (0.10, False)])
def test_s2_push_only_plan_is_judged_on_the_push(s2, box_shift, expect):
    """A plan that only pushes the trolley (make demo's task) does not need the box on the deck,
    but must not knock it off where it was."""
    s2.reset()
    initial = {oid: s2.object_pose(oid) for oid in s2.world.objects}
    p0 = initial["trolley"][0]
    plan = _plan("s2_trolley", objects={"trolley": (np.array([p0, p0, p0 + [0.25, 0, 0]]), np.tile([1.0, 0, 0, 0], (3, 1)))})
    d = s2.data
    t, b = _free_qpos(s2, "trolley"), _free_qpos(s2, "box")
    d.qpos[t] += 0.27
    d.qpos[b] += box_shift
    mujoco.mj_forward(s2.model, d)
    out = evaluate(s2, plan, initial, fell=False)
    assert out.success is expect, out.detail
    assert f"box not moved by the plan, {box_shift * 100:.1f} cm from where it was" in out.detail
    assert "trolley moved 0.27 m forward, planned 0.25 m" in out.detail
    assert not evaluate(s2, plan, initial, fell=True).success


def test_generic_definition(s1):
    s1.reset()
    initial = {oid: s1.object_pose(oid) for oid in s1.world.objects}
    here = s1.base_pose()[0]
    assert evaluate(s1, _plan("case_x", base_end=here + [0.05, 0, 0]), initial, fell=False).success
    out = evaluate(s1, _plan("case_x", base_end=here + [0.2, 0, 0]), initial, fell=False)
    assert not out.success and "final pelvis 20.0 cm" in out.detail
    p = s1.object_pose("box")[0]
    objs = {"box": (np.array([p, p, p + [0, 0, 0.1]]), np.tile([1.0, 0, 0, 0], (3, 1)))}
    out = evaluate(s1, _plan("case_x", objects=objs), initial, fell=False)
    assert not out.success and "box 10.0 cm from its planned final position" in out.detail
