"""world: MjSpec worlds build for S1, S2 and off-grid parameters with the requested objects, torque
motors, camera and render settings; S1 geometry makes the box necessary to reach the basket."""

import mujoco
import numpy as np
import pytest

from lomanip_sim import frames
from lomanip_sim.robot_model import G1_JOINT_NAMES, G1_MASS, G1_STAND_QPOS, HAND_SITES, hand_reach
from lomanip_sim.scenario import load_scenario
from lomanip_sim.world import SCENE_CAMERA, WorldBuildError, build_world


@pytest.fixture(scope="module")
def s1():
    return build_world(load_scenario("s1_basket"))


@pytest.fixture(scope="module")
def s2():
    return build_world(load_scenario("s2_trolley"))


def _check_robot(world):
    m = world.model
    assert m.opt.timestep <= 0.002
    assert m.nu == 29
    assert np.all(m.actuator_gaintype == mujoco.mjtGain.mjGAIN_FIXED)
    assert np.all(m.actuator_biastype == mujoco.mjtBias.mjBIAS_NONE)  # motors, not servos
    assert np.allclose(m.actuator_gainprm[:, 0], 1.0)
    assert np.allclose(m.actuator_ctrlrange[world.actuator_ids, 1], world.torque_limits)
    assert np.allclose(m.actuator_ctrlrange[world.actuator_ids, 0], -world.torque_limits)
    pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    assert abs(m.body_subtreemass[pelvis] - G1_MASS) < 0.01  # hand proxies add no mass
    for s in list(HAND_SITES.values()) + ["left_foot", "right_foot", "imu_in_pelvis", "imu_in_torso"]:
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) >= 0
    assert np.allclose(world.stand_qpos[world.joint_qpos_adr], G1_STAND_QPOS[7:])
    assert [m.joint(int(j)).name for j in m.actuator_trnid[world.actuator_ids, 0]] == list(G1_JOINT_NAMES)
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, SCENE_CAMERA)
    assert cam >= 0 and tuple(m.cam_resolution[cam]) == (640, 480)
    assert m.vis.quality.shadowsize == 0 and m.vis.quality.offsamples == 0
    assert not np.any(m.light_castshadow)
    assert m.vis.global_.offwidth >= 640 and m.vis.global_.offheight >= 480


def test_s1_objects(s1):
    _check_robot(s1)
    o = s1.objects
    assert {k: v.object_class for k, v in o.items()} == {"box": "box", "shelf": "shelf", "basket": "basket"}
    assert o["box"].movable and o["basket"].movable and not o["shelf"].movable
    assert o["box"].mass == pytest.approx(2.5) and o["basket"].mass == pytest.approx(0.5)
    box = o["box"].primitives[0]
    assert box.type == "box" and box.solid_primitive_dimensions() == pytest.approx([0.4, 0.4, 0.3])
    # Solid box inertia about the CoM: m/12 (b^2 + c^2)
    assert o["box"].inertia[0, 0] == pytest.approx(2.5 / 12 * (0.4**2 + 0.3**2), rel=1e-6)
    assert len(o["shelf"].primitives) >= 5 and len(o["basket"].primitives) == 5


def test_s2_objects_and_trolley_joints(s2):
    _check_robot(s2)
    o = s2.objects
    assert {k: v.object_class for k, v in o.items()} == {"box": "box", "table": "table", "trolley": "trolley"}
    p = s2.params
    assert o["trolley"].mass == pytest.approx(p.trolley_mass + 4 * p.wheel_mass)
    assert o["box"].initial_pos[2] == pytest.approx(p.table_size[2] + p.box_size[2] / 2)
    m = s2.model
    hinge = mujoco.mjtJoint.mjJNT_HINGE
    names = {m.joint(j).name: (m.jnt_type[j], tuple(m.jnt_axis[j])) for j in range(m.njnt)}
    for w in ("rl", "rr", "fl", "fr"):
        assert names[f"trolley_wheel_{w}_roll"] == (hinge, (0.0, 1.0, 0.0))
    for c in ("fl", "fr"):
        assert names[f"trolley_caster_{c}_swivel"] == (hinge, (0.0, 0.0, 1.0))
    assert "trolley_caster_rl_swivel" not in names  # rear wheels do not swivel
    prim_names = {pr.name for pr in o["trolley"].primitives}
    assert {"trolley_handle", "trolley_deck", "trolley_wheel_rl_geom"} <= prim_names


def test_off_grid_parameters_build():
    p = load_scenario("s1_basket", {"box_mass": 3.3, "box_yaw": 0.37, "box_size": [0.35, 0.45, 0.28],
                                    "shelf_size": [0.35, 0.9, 1.45], "basket_mass": 0.8})  # fmt: skip
    w = build_world(p)
    assert w.objects["box"].mass == pytest.approx(3.3)
    assert frames.quat_to_yaw(w.objects["box"].initial_quat) == pytest.approx(0.37)
    assert w.objects["basket"].initial_pos[2] == pytest.approx(1.45)
    q = load_scenario("s2_trolley", {"box_mass": 6.1, "box_yaw": -0.9, "trolley_mass": 12.5, "trolley_yaw": 0.3,
                                     "camera_width": 320, "camera_height": 240})  # fmt: skip
    w2 = build_world(q)
    assert w2.objects["trolley"].mass == pytest.approx(12.5 + 4 * q.wheel_mass)
    assert frames.quat_to_yaw(w2.objects["trolley"].initial_quat) == pytest.approx(0.3)
    with pytest.raises(WorldBuildError):
        build_world(load_scenario("s2_trolley", {"trolley_handle_height": 0.2}))


def test_s1_basket_needs_the_box(s1):
    """Basket rim is above the G1's ground reach, but reachable standing on the box at the shelf."""
    p = s1.params
    rim_z = p.shelf_size[2] + p.basket_size[2]
    ground = hand_reach(samples=2000, refine_iters=800)
    print(f"\nmax hand height from the ground {ground.max_height:.3f} m, basket rim {rim_z:.3f} m")
    assert rim_z - ground.max_height > 0.05
    # Robot on the box pushed against the shelf front, facing the shelf (shelf yaw 0 in defaults).
    shelf_front_x = p.shelf_position[0] - p.shelf_size[0] / 2
    base = (shelf_front_x - p.box_size[0] / 2 - 0.02, p.shelf_position[1], p.box_size[2] + 0.79)
    basket = s1.objects["basket"]
    front = next(pr for pr in basket.primitives if pr.name == "basket_front")
    grasp = frames.transform_point(basket.initial_pos, basket.initial_quat, front.pos + [0, 0, front.size[2]])
    on_box = hand_reach(target=grasp, base_pos=base, samples=2000, refine_iters=800)
    print(f"hand-to-rim distance standing on the box: {on_box.distance:.3f} m (rim at {grasp.round(3)})")
    assert on_box.distance < 0.02
    # Sanity: the box top fits both feet, the shelf is taller than the robot, basket sits on the top.
    assert min(p.box_size[:2]) >= 0.35 and p.shelf_size[2] > 1.32
    assert basket.initial_pos[2] == pytest.approx(p.shelf_size[2])


def test_s2_geometry_sane(s2):
    p = s2.params
    assert 0.6 <= p.table_size[2] <= 0.8
    assert p.trolley_size[2] < p.table_size[2] < p.trolley_handle_height < 1.0
    # objects do not overlap at the start: trolley footprint clear of the table footprint
    t_xy, tr_xy = np.array(p.table_position), np.array(p.trolley_position)
    assert abs(t_xy[1] - tr_xy[1]) > (p.table_size[1] + p.trolley_size[1]) / 2


def test_noslip_pass_is_a_scenario_parameter():
    """MuJoCo's noslip post-solve runs 10 iterations by default (a held box does not creep in the
    hands); 0 turns it off; a negative count is refused with a one-line ScenarioError."""
    from lomanip_sim.scenario import ScenarioError, load_scenario
    from lomanip_sim.world import build_world

    assert build_world(load_scenario("s1_basket")).model.opt.noslip_iterations == 10
    assert build_world(load_scenario("s2_trolley", {"noslip_iterations": 0})).model.opt.noslip_iterations == 0
    with pytest.raises(ScenarioError, match="noslip_iterations"):
        load_scenario("s1_basket", {"noslip_iterations": -1})


def test_friction_model_is_a_scenario_parameter():
    """MuJoCo's friction impedance ratio and cone: 10 and elliptic by default (every world, the small
    cases' too), settable, and bad values refused with a one-line ScenarioError."""
    import mujoco

    from lomanip_sim.scenario import ScenarioError, load_scenario
    from lomanip_sim.scene_world import build_scene_world, scene_params
    from lomanip_sim.world import build_world

    opt = build_world(load_scenario("s1_basket")).model.opt
    assert (opt.impratio, opt.cone) == (10.0, mujoco.mjtCone.mjCONE_ELLIPTIC)
    opt = build_scene_world([]).model.opt
    assert (opt.impratio, opt.cone) == (10.0, mujoco.mjtCone.mjCONE_ELLIPTIC)
    opt = build_world(load_scenario("s2_trolley", {"impratio": 1.0, "friction_cone": "pyramidal"})).model.opt
    assert (opt.impratio, opt.cone) == (1.0, mujoco.mjtCone.mjCONE_PYRAMIDAL)
    assert build_scene_world([], params=scene_params({"friction_cone": "pyramidal"})).model.opt.cone == 0
    with pytest.raises(ScenarioError, match="impratio"):
        load_scenario("s1_basket", {"impratio": 0.0})
    with pytest.raises(ScenarioError, match="friction_cone must be one of pyramidal, elliptic"):
        load_scenario("s1_basket", {"friction_cone": "round"})
    with pytest.raises(ScenarioError, match="friction_cone.*a string"):
        scene_params({"friction_cone": 1})
    with pytest.raises(ScenarioError, match="unknown parameter 'box_mass'"):
        scene_params({"box_mass": 3.0})
