"""hand_approach: a hand rising through the bar it is about to grasp is lifted out of it, smoothly.

A small MuJoCo model (a free "trolley" with a handle bar, a mocap "hand" with a 13 x 7 x 11 cm box
geom and a site) stands in for the G1 and the push of make demo: the planned hand rises right
through the bar and grasps it from behind and above (normal (-0.8, 0, 0.6)).
"""

import mujoco
import numpy as np

from lomanip_sim.hand_approach import approach_lift
from lomanip_sim.hand_detour import HandBoxProbe, movable_bodies, static_obstacle_geoms
from mocap_hand import hand_ids, scene

_OBJECTS = """
    <body name="trolley" pos="0.85 0 0"><freejoint/>
      <geom name="handle" type="cylinder" size="0.016 0.225" pos="-0.385 0 0.85" euler="90 0 0"/>
    </body>
"""


def _setup():
    m = mujoco.MjModel.from_xml_string(scene(_OBJECTS, site_offset=0.0, box_offset=0.06))
    hand, site, hg = hand_ids(m)
    t = np.round(np.arange(0.0, 3.001, 0.01), 6)
    (b,) = movable_bodies(m, hand)
    pose = (np.repeat(np.array([[0.85, 0.0, 0.0]]), len(t), 0), np.repeat(np.array([[1.0, 0, 0, 0]]), len(t), 0))
    probe = HandBoxProbe(m, hg, site, static_obstacle_geoms(m, hand), {b: pose})
    return t, probe


def test_rise_through_the_bar_is_lifted_out_and_lands_along_the_normal():
    t, probe = _setup()
    start = 2.6
    u = np.clip((t - 1.8) / 0.7, 0.0, 1.0)  # rises at the bar's x from 0.65 to 0.95 m (box 6 cm ahead of the site)
    pos = np.stack([np.full_like(t, 0.40), np.zeros_like(t), 0.65 + 0.30 * u], axis=1)
    rot = np.repeat(np.eye(3)[None], len(t), 0)
    n = np.array([-0.8, 0.0, 0.6])
    normals = np.repeat(n[None], len(t), 0)
    before = np.array([probe.clearance(p, R, i)[1] for i, (p, R) in enumerate(zip(pos, rot))])
    assert before[(t > 2.0) & (t < 2.5)].min() < -0.01  # the plan goes through the bar
    lift = approach_lift(t, pos, rot, normals, start, probe, window=0.8, margin=0.01, spread=0.4, taper=0.4, post=0.2)
    moved = pos + lift[:, None] * normals
    after = np.array([probe.clearance(p, R, i)[1] for i, (p, R) in enumerate(zip(moved, rot))])
    sel = (t >= start - 0.8) & (t < start - 0.1)
    assert after[sel].min() >= 0.01 - 1e-6  # kept out of the bar before the final approach
    assert np.all(lift[t >= start + 0.4] == 0.0) and np.all(lift[t < start - 0.8 - 0.4] == 0.0)  # last lift + taper
    assert np.abs(np.diff(lift)).max() < 0.01  # smooth: under 1 m/s on the 10 ms grid
