"""hand_detour: a hand reference that sweeps through a table top is shifted round it, contacts untouched.

A small MuJoCo model (a fixed "table top" box, a free "box" object, a mocap "hand" body carrying a
13 x 7 x 11 cm box geom and a site) stands in for the G1 so the geometry is exact and fast.
"""

import mujoco
import numpy as np

from lomanip_sim.hand_detour import HandBoxProbe, ObjectsAsObstacles, detour, movable_bodies, static_obstacle_geoms
from mocap_hand import hand_ids, scene

_OBJECTS = """
    <body name="table" pos="0.75 0 0.68"><geom name="top" type="box" size="0.3 0.4 0.02"/></body>
    <body name="box" pos="0.75 0 0.825"><freejoint/><geom name="box_geom" type="box" size="0.15 0.15 0.125"/></body>
"""


def _setup():
    m = mujoco.MjModel.from_xml_string(scene(_OBJECTS, site_offset=0.1, box_offset=0.1))
    hand, site, hg = hand_ids(m)
    geoms = static_obstacle_geoms(m, robot_root=hand)
    return m, hand, geoms, site, hg


def test_static_and_movable_geoms():
    m, hand, geoms, _site, _hg = _setup()
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in geoms]
    assert names == ["top"]  # not the floor plane, not the free box, not the hand
    assert [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in movable_bodies(m, hand)] == ["box"]


def test_path_through_the_table_edge_is_shifted_round_it():
    m, _hand, geoms, site, hg = _setup()
    probe = HandBoxProbe(m, hg, site, geoms)
    # S2-like: from in front of and below the top (0.35, 0.55) to above it (0.65, 0.80) in 0.6 s
    t = np.round(np.arange(0.0, 2.001, 0.01), 6)
    u = np.clip((t - 0.7) / 0.6, 0.0, 1.0)
    pos = np.stack([0.35 + 0.30 * u, np.full_like(t, -0.2), 0.55 + 0.25 * u], axis=1)
    rot = np.repeat(np.eye(3)[None], len(t), 0)
    contact = t >= 1.8
    before = np.array([probe.clearance(p, R)[0] for p, R in zip(pos, rot)])
    assert before.min() < -0.05  # the straight path goes through the top
    shifted, found = detour("right_hand", t, pos, rot, contact, probe, margin=0.02, pre_contact=0.2)
    after = np.array([probe.clearance(p, R)[0] for p, R in zip(shifted, rot)])
    assert len(found) == 1 and found[0].direction is not None
    assert after.min() >= 0.02 - 1e-6
    assert np.allclose(shifted[contact], pos[contact])  # contact phases keep the plan
    assert np.allclose(shifted[t >= 1.6], pos[t >= 1.6])  # and the shift is gone pre_contact before
    assert np.allclose(shifted[t <= 0.05], pos[t <= 0.05])
    assert np.max(np.linalg.norm(np.diff(shifted, axis=0), axis=1)) < 0.05  # continuous (< 5 m/s)


def test_clear_path_is_left_alone():
    m, _hand, geoms, site, hg = _setup()
    probe = HandBoxProbe(m, hg, site, geoms)
    t = np.round(np.arange(0.0, 1.001, 0.01), 6)
    pos = np.stack([np.full_like(t, 0.2), np.linspace(-0.3, 0.3, len(t)), np.full_like(t, 0.9)], axis=1)
    rot = np.repeat(np.eye(3)[None], len(t), 0)
    shifted, found = detour("left_hand", t, pos, rot, np.zeros(len(t), bool), probe)
    assert found == [] and np.array_equal(shifted, pos)


def test_path_through_a_movable_object_is_shifted_round_it_when_objects_count_as_obstacles():
    """``ObjectsAsObstacles``: a free hand that sweeps through the free box (at its planned pose) well
    before a contact is shifted round it (``WbcGains.hand_detour_movable``); the plain probe only
    keeps the plan's own clearance from movable objects and leaves it as it is."""
    m, hand, geoms, site, hg = _setup()
    box = movable_bodies(m, hand)[0]
    t = np.round(np.arange(0.0, 2.001, 0.01), 6)
    still = (np.repeat([[0.75, 0.0, 0.825]], len(t), 0), np.repeat([[1.0, 0.0, 0.0, 0.0]], len(t), 0))
    probe = HandBoxProbe(m, hg, site, geoms, {box: still})
    # sideways through the box's near side (4.6 cm into it) over 0.4-1.0 s, contact from 1.8 s
    u = np.clip((t - 0.4) / 0.6, 0.0, 1.0)
    pos = np.stack([np.full_like(t, 0.58), -0.4 + 0.8 * u, np.full_like(t, 0.93)], axis=1)
    rot = np.repeat(np.eye(3)[None], len(t), 0)
    contact = t >= 1.8
    before = np.array([probe.clearance(p, R, i)[1] for i, (p, R) in enumerate(zip(pos, rot))])
    assert before.min() < -0.04
    plain, found_plain = detour("left_hand", t, pos, rot, contact, probe)
    assert found_plain == [] and np.array_equal(plain, pos)
    shifted, found = detour("left_hand", t, pos, rot, contact, ObjectsAsObstacles(probe), margin=0.02, pre_contact=0.0)
    after = np.array([probe.clearance(p, R, i)[1] for i, (p, R) in enumerate(zip(shifted, rot))])
    assert len(found) == 1 and found[0].direction is not None
    assert after.min() >= 0.02 - 1e-6
    assert np.allclose(shifted[contact], pos[contact])
