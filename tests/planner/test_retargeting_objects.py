"""Retargeting keeps the robot clear of the scene's objects (issue 5).

S1's "pick up the box" keyframe used to put both knees and thighs 9-10 cm inside the box: the IK
knew only self-collision. Distances here are measured on a separate MuJoCo scene (the G1 plus the
object as a static geom), not with the retargeter's own bookkeeping.
"""
from __future__ import annotations

import mink
import mujoco
import numpy as np
import pytest

from lomanip_planner.keyframes import obstacles_of
from lomanip_planner.retargeting import (OBJECT_CLEARANCE, OBJECT_PENETRATION_TOLERANCE, RETARGETING_INFEASIBLE,
                                         LimbTarget, ObjectClearanceLimit, ObjectClearanceTask, ObjectProximity,
                                         Obstacle, RetargetTarget, Retargeter, RetargetingError)
from lomanip_sim import frames
from lomanip_sim.world import build_robot_model
from lomanip_to.problem import Primitive, SceneObject

#: S1's box (0.4 x 0.4 x 0.3 m on the floor) and its pick as perception transferred it: the
#: demonstrator's feet 18 cm behind the box's near face, hands on its side faces
_BOX = Obstacle("box", "box", np.array([0.2, 0.2, 0.15]), np.array([0.7, 0.0, 0.15]))
_FEET = (LimbTarget("left_foot", np.array([0.3187, 0.1070, 0.0]), object_id="floor"),
         LimbTarget("right_foot", np.array([0.3163, -0.1376, 0.0]), object_id="floor"))
_HANDS = (LimbTarget("left_hand", np.array([0.7214, 0.2, 0.2077]), np.array([0.0, 1.0, 0.0]), "box"),
          LimbTarget("right_hand", np.array([0.7149, -0.2, 0.2211]), np.array([0.0, -1.0, 0.0]), "box"))
_PRIOR = {"left_hip_pitch_joint": -2.397, "left_knee_joint": 2.095, "right_hip_pitch_joint": -2.397,
          "right_knee_joint": 2.095, "waist_pitch_joint": 0.977, "left_shoulder_pitch_joint": -0.903,
          "left_elbow_joint": 0.980, "right_shoulder_pitch_joint": -0.906, "right_elbow_joint": 0.988}
#: bodies that may touch the box in the pick: the wrists and hands holding it
_HOLDING = {f"{side}_{link}" for side in ("left", "right") for link in ("wrist_roll_link", "wrist_pitch_link",
                                                                         "wrist_yaw_link")}


def _pick(obstacles: tuple[Obstacle, ...]) -> RetargetTarget:
    return RetargetTarget(_FEET + _HANDS, base_orientation_wxyz=frames.yaw_to_quat(0.0), joint_prior=_PRIOR,
                          pelvis_height_ratio=0.494, obstacles=obstacles)


def _box_distances(qpos: np.ndarray, box: Obstacle) -> dict[str, float]:
    """Robot body -> signed distance to ``box`` (m) on a scene of its own: the G1 and a static box."""
    from lomanip_sim.robot_model import g1_mjcf_path
    from lomanip_sim.world import _add_hands

    spec = mujoco.MjSpec.from_file(str(g1_mjcf_path()))
    _add_hands(spec)
    geom = spec.worldbody.add_geom()
    geom.name, geom.type, geom.size = "box", mujoco.mjtGeom.mjGEOM_BOX, list(box.size)
    geom.pos, geom.quat = list(box.position), list(box.quat_wxyz)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    box_id, fromto, out = model.geom("box").id, np.zeros(6), {}
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != 0 and model.geom_contype[g]:
            body = model.body(model.geom_bodyid[g]).name
            out[body] = min(out.get(body, np.inf), mujoco.mj_geomDistance(model, data, g, box_id, 1.0, fromto))
    return out


@pytest.fixture(scope="module")
def retargeter() -> Retargeter:
    return Retargeter()


def test_ik_model_is_the_robot_model_plus_obstacles(retargeter):
    robot = build_robot_model()
    m = retargeter.model
    assert (m.nq, m.nv) == (robot.nq, robot.nv)
    assert [m.geom(g).name for g in range(robot.ngeom)] == [robot.geom(g).name for g in range(robot.ngeom)]
    assert [m.body(b).name for b in range(robot.nbody)] == [robot.body(b).name for b in range(robot.nbody)]
    d, d_robot = mujoco.MjData(m), mujoco.MjData(robot)
    d.qpos[:] = d_robot.qpos[:] = retargeter.stand
    mujoco.mj_kinematics(m, d)
    mujoco.mj_kinematics(robot, d_robot)
    np.testing.assert_allclose(d.site_xpos, d_robot.site_xpos, atol=1e-12)


def test_pick_keyframe_keeps_the_legs_out_of_the_box(retargeter):
    """The box between the knees: without the box in the IK both knees end 9-10 cm inside it."""
    res = retargeter.solve(_pick((_BOX,)))
    assert max(res.residuals.values()) <= 0.01                       # the hands still hold the box
    assert res.within_joint_limits and res.min_self_distance >= 0.0
    assert res.min_object_distance >= OBJECT_CLEARANCE - 1e-3
    dist = _box_distances(res.qpos, _BOX)
    legs_and_arms = {b: d for b, d in dist.items() if b not in _HOLDING}
    closest = sorted(legs_and_arms.items(), key=lambda kv: kv[1])[:3]
    assert min(legs_and_arms.values()) >= OBJECT_CLEARANCE - 1e-3, closest
    for side in ("left", "right"):
        assert dist[f"{side}_knee_link"] >= OBJECT_CLEARANCE - 1e-3


def test_without_obstacles_the_same_pick_is_inside_the_box(retargeter):
    """The case above is a real one: the robot-only IK puts the knees inside the box."""
    res = retargeter.solve(_pick(()))
    assert res.min_object_distance == np.inf
    dist = _box_distances(res.qpos, _BOX)
    assert min(dist["left_knee_link"], dist["right_knee_link"]) < -0.05


def test_a_keyframe_left_inside_an_object_is_infeasible(retargeter):
    """A slab through the robot's waist that no start can leave: named, with the infeasible code."""
    slab = Obstacle("slab", "box", np.array([1.5, 1.5, 0.1]), np.array([0.0, 0.0, 0.6]))
    with pytest.raises(RetargetingError) as err:
        retargeter.solve(RetargetTarget(_FEET, obstacles=(slab,)))
    assert err.value.code == RETARGETING_INFEASIBLE
    assert "inside slab" in str(err.value)


def test_a_foot_may_stand_on_the_object_it_touches(retargeter):
    """Feet on the box top are not kept clear of the box (their soles rest on it)."""
    feet = tuple(LimbTarget(f, np.array([0.7, s * 0.1, 0.30]), object_id="box")
                 for f, s in (("left_foot", 1), ("right_foot", -1)))
    res = retargeter.solve(RetargetTarget(feet, base_orientation_wxyz=frames.yaw_to_quat(0.0), obstacles=(_BOX,)))
    assert max(res.residuals.values()) <= 0.01
    assert res.min_object_distance >= -OBJECT_PENETRATION_TOLERANCE


def _pose_near_box(retargeter: Retargeter, shift: float) -> np.ndarray:
    q = retargeter.stand.copy()
    q[0] = shift
    rng = np.random.default_rng(3)
    q[7:] += rng.normal(0.0, 0.15, q.size - 7)
    return q


def test_clearance_limit_rows_are_minks(retargeter):
    """ObjectClearanceLimit gives mink's CollisionAvoidanceLimit rows for the near pairs."""
    targets = {t.limb: t for t in _FEET + _HANDS}
    retargeter._set_obstacles((_BOX,), targets)
    pairs = [(r, g) for r, g, _ in retargeter._object_pairs]
    proximity = ObjectProximity(pairs, 0.05)
    ours = ObjectClearanceLimit(proximity, OBJECT_CLEARANCE)
    minks = mink.CollisionAvoidanceLimit(retargeter.model, [([r], [g]) for r, g in pairs],
                                         minimum_distance_from_collisions=OBJECT_CLEARANCE,
                                         collision_detection_distance=0.05)
    conf = retargeter.configuration
    checked = 0
    for shift in (0.25, 0.3, 0.35, 0.4):
        conf.update(_pose_near_box(retargeter, shift))
        a, b = ours.compute_qp_inequalities(conf, 1.0), minks.compute_qp_inequalities(conf, 1.0)
        near = np.isfinite(b.h)
        if a.G is None:
            assert not near.any()
            continue
        rows_a = sorted(zip(a.h.round(12), map(tuple, a.G.round(9))))
        rows_b = sorted(zip(b.h[near].round(12), map(tuple, b.G[near].round(9))))
        assert len(rows_a) == len(rows_b)
        for (ha, ga), (hb, gb) in zip(rows_a, rows_b):
            assert ha == pytest.approx(hb, abs=1e-9)
            np.testing.assert_allclose(ga, gb, atol=1e-7)
        checked += len(rows_a)
    assert checked > 0


def test_clearance_task_jacobian_matches_finite_differences(retargeter):
    targets = {t.limb: t for t in _FEET + _HANDS}
    retargeter._set_obstacles((_BOX,), targets)
    task = ObjectClearanceTask(ObjectProximity([(r, g) for r, g, _ in retargeter._object_pairs], 0.05),
                               OBJECT_CLEARANCE, 1.0)
    conf = retargeter.configuration
    active = 0
    for shift in (0.3, 0.35, 0.4):
        q = _pose_near_box(retargeter, shift)
        conf.update(q)
        error, jac = task.compute_error(conf), task.compute_jacobian(conf)
        rows = np.flatnonzero(error < 0.0)
        eps = 1e-6
        for k in range(conf.model.nv):
            dq = np.zeros(conf.model.nv)
            dq[k] = eps
            conf.update(q)
            conf.integrate_inplace(dq, 1.0)
            plus = task.compute_error(conf)
            conf.update(q)
            conf.integrate_inplace(-dq, 1.0)
            minus = task.compute_error(conf)
            np.testing.assert_allclose(jac[rows, k], (plus - minus)[rows] / (2 * eps), atol=1e-5)
        active += rows.size
    assert active > 0


def test_obstacles_of_a_turned_object():
    """A primitive's offset and yaw turn with the object; a cylinder becomes (radius, half height)."""
    q = frames.yaw_to_quat(np.pi / 2)   # (w, x, y, z)
    obj = SceneObject("cart", "trolley", True, (1.0, 2.0, 0.0), quat_xyzw=(q[1], q[2], q[3], q[0]),
                      primitives=[Primitive("box", (0.4, 0.2, 0.1), (0.3, 0.0, 0.5), 0.0),
                                  Primitive("cylinder", (0.04, 0.1), (0.0, 0.2, 0.1))])
    box, wheel = obstacles_of(obj)
    np.testing.assert_allclose(box.position, [1.0, 2.3, 0.5], atol=1e-12)
    np.testing.assert_allclose(box.size, [0.2, 0.1, 0.05])
    assert frames.quat_to_yaw(box.quat_wxyz) == pytest.approx(np.pi / 2)
    np.testing.assert_allclose(wheel.position, [0.8, 2.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(wheel.size, [0.1, 0.02])
    assert (box.kind, wheel.kind, box.object_id) == ("box", "cylinder", "cart")
