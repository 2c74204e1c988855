"""scene_world: a world built from a TO problem's own scene (table fixed, box free with its mass)."""

import mujoco
import numpy as np
import pytest

from lomanip_sim.robot_model import G1_STAND_QPOS
from lomanip_sim.scene_world import SceneObjectSpec, ScenePrimitive, build_scene_world, objects_from_to_problem
from lomanip_sim.simulator import Simulation
from lomanip_sim.world import WorldBuildError


def _lift_box_world(box_position=None):
    """case_lift_box's scene (its box moved to ``box_position`` if given) with the robot standing."""
    import dataclasses

    from lomanip_to import fixtures

    objects = objects_from_to_problem(fixtures.load_problem("case_lift_box"))
    if box_position is not None:
        objects = [dataclasses.replace(o, position=box_position) if o.id == "box" else o for o in objects]
    q = G1_STAND_QPOS.copy()
    q[2] = 0.78
    return build_scene_world(objects, robot_qpos=q), q


@pytest.fixture(scope="module")
def lift_box_world():
    return _lift_box_world()


def test_objects_and_robot_start(lift_box_world):
    world, q = lift_box_world
    assert set(world.objects) == {"table", "box"}
    assert world.objects["box"].movable and not world.objects["table"].movable
    assert world.objects["box"].mass == pytest.approx(1.0, rel=1e-6)
    sim = Simulation(world)
    np.testing.assert_allclose(sim.robot_qpos(), q)
    np.testing.assert_allclose(sim.object_pose("box")[0], [0.27, 0.0, 0.77])
    assert world.torque_limits.shape == (29,)
    for limb in ("left_hand_collision", "right_hand_collision"):
        assert mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_GEOM, limb) >= 0


def test_box_rests_on_table_under_physics():
    """A box on the table top (0.65 m) stays there: real contact, no fixed joint.

    The box sits 5 cm inside the table's edge: case_lift_box's own box has its centre of mass over
    the edge (0.27 m, ready to be grasped) and, left alone, slowly tips off it."""
    sim = Simulation(_lift_box_world(box_position=(0.32, 0.0, 0.77))[0])
    sim.run_for(0.5)
    p = sim.object_pose("box")[0]
    assert abs(p[2] - 0.77) < 0.002 and np.linalg.norm(p[:2] - [0.32, 0.0]) < 0.002
    assert not sim.has_fallen()


def test_bad_objects():
    box = ScenePrimitive("box", (0.1, 0.1, 0.1))
    with pytest.raises(WorldBuildError, match="positive mass"):
        build_scene_world([SceneObjectSpec("b", "box", True, (1, 0, 0.05), (1, 0, 0, 0), 0.0, (box,))])
    cone = ScenePrimitive("cone", (0.1, 0.1))
    with pytest.raises(WorldBuildError, match="unsupported primitive kind 'cone'"):
        build_scene_world([SceneObjectSpec("c", "box", False, (1, 0, 0), (1, 0, 0, 0), 0.0, (cone,))])


def test_cylinder_object():
    cyl = ScenePrimitive("cylinder", (0.4, 0.05), (0.0, 0.0, 0.2))
    w = build_scene_world([SceneObjectSpec("post", "shelf", False, (1.0, 0.5, 0.0), (1, 0, 0, 0), 0.0, (cyl,))])
    g = mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, "post_geom0")
    assert w.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER
    np.testing.assert_allclose(w.model.geom_size[g][:2], [0.05, 0.2])
