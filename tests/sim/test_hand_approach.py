"""hand_approach: a hand rising through the bar it is about to grasp is lifted out of it, smoothly;
one lowered through the bar it has let go of is lifted out the same way.

A small MuJoCo model (a free "trolley" with a handle bar, a mocap "hand" with a 13 x 7 x 11 cm box
geom and a site) stands in for the G1 and the push of make demo: the planned hand rises right
through the bar and grasps it from behind and above (normal (-0.8, 0, 0.6)).
"""

import mujoco
import numpy as np

from lomanip_sim.hand_approach import approach_lift, retreat_lift
from lomanip_sim.hand_detour import HandBoxProbe, movable_bodies, static_obstacle_geoms
from mocap_hand import hand_ids, scene

_OBJECTS = """
    <body name="trolley" pos="0.85 0 0"><freejoint/>
      <geom name="handle" type="cylinder" size="0.016 0.225" pos="-0.385 0 0.85" euler="90 0 0"/>
    </body>
"""


def _setup(trolley_x=None):
    """(grid, probe); the trolley at x = 0.85 m or along ``trolley_x(t)``."""
    m = mujoco.MjModel.from_xml_string(scene(_OBJECTS, site_offset=0.0, box_offset=0.06))
    hand, site, hg = hand_ids(m)
    t = np.round(np.arange(0.0, 3.001, 0.01), 6)
    (b,) = movable_bodies(m, hand)
    x = np.full_like(t, 0.85) if trolley_x is None else trolley_x(t)
    pose = (np.stack([x, np.zeros_like(t), np.zeros_like(t)], axis=1), np.repeat(np.array([[1.0, 0, 0, 0]]), len(t), 0))
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


def test_lowering_through_the_bar_after_the_release_is_lifted_out_from_the_release_on():
    # the trolley rolls 0.85 -> 1.10 m over 0.5-2.0 s (the probe must place it at each sample's own
    # time), the contact ends at 2.0 s, then the plan lowers the hand 25 cm through the bar
    t, probe = _setup(lambda t: 0.85 + 0.25 * np.clip((t - 0.5) / 1.5, 0.0, 1.0))
    end = 2.0
    u = np.clip((t - end) / 0.5, 0.0, 1.0)
    pos = np.stack([np.full_like(t, 0.655), np.zeros_like(t), 0.95 - 0.25 * u], axis=1)  # box over the bar at 0.715 m
    rot = np.repeat(np.eye(3)[None], len(t), 0)
    normals = np.repeat(np.array([[-0.8, 0.0, 0.6]]), len(t), 0)
    before = np.array([probe.clearance(p, R, i)[1] for i, (p, R) in enumerate(zip(pos, rot))])
    assert before[(t > end + 0.1) & (t < end + 0.5)].min() < -0.01  # the plan goes through the bar
    lift = retreat_lift(t, pos, rot, normals, end, probe, window=0.8, margin=0.01, spread=0.4, last=0.3, taper=0.3)
    moved = pos + lift[:, None] * normals
    after = np.array([probe.clearance(p, R, i)[1] for i, (p, R) in enumerate(zip(moved, rot))])
    sel = (t > end + 0.3) & (t <= end + 0.8)
    assert after[sel].min() >= 0.01 - 1e-6  # kept out of the bar once it has left
    assert after[(t > end) & (t <= end + 0.8)].min() > -0.02  # and nearly so while it rises (the plan drops 5 cm in 0.1 s)
    assert np.all(lift[t <= end] == 0.0)  # nothing while the contact lasts: the hand leaves along the normal
    assert np.all(lift[t > end + 0.8 + 0.4] == 0.0)  # last checked sample + the kernel's half-width
    assert np.abs(np.diff(lift)).max() < 0.01  # smooth: under 1 m/s on the 10 ms grid


class _TwoSlabs:
    """A probe stand-in: along x, object A fills [0, 0.1] m and object B [0.115, 0.4] m; the signed
    clearance of the hand's point is its distance to the nearer slab (negative inside one)."""

    @staticmethod
    def clearance(p, R, i=None):
        x = float(p[0])
        if x <= 0.1:
            return 1.0, -min(x, 0.1 - x) if x >= 0.0 else -x
        if x < 0.115:
            return 1.0, min(x - 0.1, 0.115 - x)
        return 1.0, -min(x - 0.115, 0.4 - x) if x <= 0.4 else x - 0.4


def test_where_no_lift_is_clear_the_least_bad_one_is_taken_instead_of_the_largest():
    """Lifting out of A along +x drives the hand into B before any lift keeps the 1 cm margin: the
    largest lift (25 cm) lands deep in B; ``least_bad`` stops in the 1.5 cm gap between them."""
    t = np.round(np.arange(0.0, 2.0, 0.01), 6)
    pos = np.tile([0.05, 0.0, 0.0], (len(t), 1))
    rot = np.repeat(np.eye(3)[None], len(t), 0)
    normals = np.tile([1.0, 0.0, 0.0], (len(t), 1))
    kw = dict(window=0.8, margin=0.01, spread=0.2, last=0.1, taper=0.1)
    mid = int(np.searchsorted(t, 1.5))  # in the window before a contact at 2.0 s
    largest = approach_lift(t, pos, rot, normals, 2.0, _TwoSlabs, **kw)
    least = approach_lift(t, pos, rot, normals, 2.0, _TwoSlabs, least_bad=True, **kw)
    assert abs(largest[mid] - 0.25) < 1e-9
    assert abs(least[mid] - 0.06) < 1e-9  # x = 0.11 m: 1 cm from A, 0.5 cm from B
    assert _TwoSlabs.clearance(pos[mid] + least[mid] * normals[mid], None)[1] > 0.0
