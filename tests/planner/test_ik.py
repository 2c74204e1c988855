"""The keyframe IK's tasks and descent (lomanip_planner.ik), on the G1 model without ROS."""
from __future__ import annotations

import mink
import numpy as np
import pytest

from lomanip_planner.ik import ComOverFeetTask, PelvisFloorTask, minimise, task_cost
from lomanip_planner.retargeting import FEET
from lomanip_sim.world import build_robot_model


@pytest.fixture(scope="module")
def model():
    return build_robot_model()


def _bent(model) -> np.ndarray:
    rng = np.random.default_rng(3)
    q = model.key("stand").qpos.copy()
    q[7:] += rng.uniform(-0.2, 0.2, q.size - 7)
    q[7:] = np.clip(q[7:], model.jnt_range[1:, 0], model.jnt_range[1:, 1])
    return q


def _finite_difference_jacobian(configuration: mink.Configuration, task: mink.Task, eps: float = 1e-6) -> np.ndarray:
    q0 = configuration.q.copy()
    columns = []
    for i in range(configuration.nv):
        dv = np.zeros(configuration.nv)
        dv[i] = eps
        configuration.update(q0)
        configuration.integrate_inplace(dv, 1.0)
        plus = task.compute_error(configuration)
        configuration.update(q0)
        configuration.integrate_inplace(-dv, 1.0)
        minus = task.compute_error(configuration)
        columns.append((plus - minus) / (2 * eps))
    configuration.update(q0)
    return np.column_stack(columns)


def test_com_over_feet_jacobian_matches_finite_differences(model):
    configuration = mink.Configuration(model, _bent(model))
    task = ComOverFeetTask(FEET)
    np.testing.assert_allclose(task.compute_jacobian(configuration),
                               _finite_difference_jacobian(configuration, task), atol=1e-6)


def test_pelvis_floor_is_one_sided(model):
    configuration = mink.Configuration(model, _bent(model))
    z = configuration.data.body("pelvis").xpos[2]
    above = PelvisFloorTask(z - 0.05, cost=3.0)
    assert above.compute_error(configuration)[0] == 0.0
    assert not np.any(above.compute_jacobian(configuration))
    below = PelvisFloorTask(z + 0.05, cost=3.0)
    assert below.compute_error(configuration)[0] == pytest.approx(-0.05)
    np.testing.assert_allclose(below.compute_jacobian(configuration),
                               _finite_difference_jacobian(configuration, below), atol=1e-6)


def test_pelvis_ceiling_pulls_down_only_above_it(model):
    configuration = mink.Configuration(model, _bent(model))
    z = configuration.data.body("pelvis").xpos[2]
    inside = PelvisFloorTask(z - 0.05, cost=30.0, ceiling=z + 0.05)
    assert inside.compute_error(configuration)[0] == 0.0
    assert not np.any(inside.compute_jacobian(configuration))
    above = PelvisFloorTask(-np.inf, cost=30.0, ceiling=z - 0.05)
    assert above.compute_error(configuration)[0] == pytest.approx(0.05)
    np.testing.assert_allclose(above.compute_jacobian(configuration),
                               _finite_difference_jacobian(configuration, above), atol=1e-6)


def test_descent_reaches_a_reachable_hand_target_and_stops(model):
    configuration = mink.Configuration(model, model.key("stand").qpos.copy())
    hand = mink.FrameTask("left_hand", "site", position_cost=100.0, orientation_cost=0.0)
    goal = configuration.get_transform_frame_to_world("left_hand", "site").translation() + [0.10, 0.05, 0.15]
    hand.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.identity(), goal))
    posture = mink.PostureTask(model, cost=1e-2)
    posture.set_target(model.key("stand").qpos)
    tasks = [hand, posture]
    start = task_cost(configuration, tasks)
    result = minimise(configuration, tasks, [mink.ConfigurationLimit(model)], max_iterations=200)
    assert result.converged and result.iterations < 200
    assert result.cost < 1e-3 * start
    reached = configuration.get_transform_frame_to_world("left_hand", "site").translation()
    assert np.linalg.norm(reached - goal) < 1e-3


def test_descent_never_raises_the_cost(model, monkeypatch):
    """Each QP is built at an iterate no worse than the last (the old fixed-step IK oscillated)."""
    import lomanip_planner.ik as ik

    configuration = mink.Configuration(model, _bent(model))
    hand = mink.FrameTask("right_hand", "site", position_cost=1000.0, orientation_cost=0.0)
    hand.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.identity(), np.array([0.6, -0.2, 0.2])))
    tasks = [hand, PelvisFloorTask(0.6, cost=3.0), ComOverFeetTask(FEET)]
    iterates = []
    build = mink.build_ik

    def recorded(c, t, dt, **kwargs):
        iterates.append(task_cost(c, t))
        return build(c, t, dt, **kwargs)

    monkeypatch.setattr(ik.mink, "build_ik", recorded)
    result = minimise(configuration, tasks, [mink.ConfigurationLimit(model)], max_iterations=50)
    assert len(iterates) > 10
    assert np.all(np.diff(iterates) <= 1e-12)
    assert result.cost < 1e-2 * iterates[0]


def test_com_over_feet_with_a_load_balances_robot_and_load_together(model):
    configuration = mink.Configuration(model, _bent(model))
    plain, loaded = ComOverFeetTask(FEET), ComOverFeetTask(FEET)
    point = np.array([0.5, 0.1, 0.9])
    loaded.set_load(5.0, point)
    robot = float(model.body_subtreemass[1])
    np.testing.assert_allclose(loaded.compute_error(configuration),
                               (robot * plain.compute_error(configuration) + 5.0 * (point[:2] - _mid_feet(configuration)))
                               / (robot + 5.0), atol=1e-12)
    np.testing.assert_allclose(loaded.compute_jacobian(configuration),
                               _finite_difference_jacobian(configuration, loaded), atol=1e-6)
    loaded.set_load(0.0)
    np.testing.assert_allclose(loaded.compute_error(configuration), plain.compute_error(configuration))


def _mid_feet(configuration: mink.Configuration) -> np.ndarray:
    return np.mean([configuration.data.site(f).xpos[:2] for f in FEET], axis=0)


def test_stalled_descent_stops_early_near_the_full_descents_cost(model):
    """The stall stop cuts the slow tail (an unreachable hand, the weak posture prior settling)
    for well under 1 % of the cost; without a window the descent runs on."""
    def descend(**kwargs):
        configuration = mink.Configuration(model, _bent(model))
        hand = mink.FrameTask("right_hand", "site", position_cost=100.0, orientation_cost=0.0)
        hand.set_target(mink.SE3.from_rotation_and_translation(mink.SO3.identity(), np.array([1.2, -0.6, 1.6])))
        posture = mink.PostureTask(model, cost=1e-2)
        posture.set_target(model.key("stand").qpos)
        feet = []
        for foot in FEET:   # planted where they are: the hand's target is out of reach
            task = mink.FrameTask(foot, "site", position_cost=1000.0, orientation_cost=200.0)
            task.set_target(configuration.get_transform_frame_to_world(foot, "site"))
            feet.append(task)
        return minimise(configuration, [hand, posture, ComOverFeetTask(FEET), *feet],
                        [mink.ConfigurationLimit(model)], max_iterations=300, **kwargs)

    full = descend()
    stalled = descend(stall_window=10, stall_tolerance=1e-3)
    assert stalled.stalled and stalled.converged and not full.stalled
    assert stalled.iterations < full.iterations
    assert stalled.cost <= full.cost * 1.01
