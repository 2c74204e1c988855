"""A mocap "hand" (the G1 hand's 13 x 7 x 11 cm collision box and a site) in a small MuJoCo scene.

Shared by the hand_detour and hand_approach tests: the geometry is exact and the models load in
milliseconds, so the reference corrections are tested without the G1.
"""

import mujoco

HAND_HALF_SIZE = "0.066 0.033 0.053"


def scene(objects_xml: str, site_offset: float, box_offset: float) -> str:
    """MJCF with a floor, ``objects_xml`` and the mocap hand (its site and box that far ahead, m)."""
    return f"""
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    {objects_xml}
    <body name="hand" mocap="true" pos="0 0 1">
      <site name="hand_site" pos="{site_offset} 0 0"/>
      <geom name="hand_box" type="box" size="{HAND_HALF_SIZE}" pos="{box_offset} 0 0" contype="1" conaffinity="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def hand_ids(m: mujoco.MjModel) -> tuple[int, int, int]:
    """(hand body, hand site, hand box geom) ids."""
    return (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "hand"),
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "hand_site"),
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "hand_box"))
