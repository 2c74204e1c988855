"""contact_forces: the measured limb forces balance the robot's weight and point the right way."""

import mujoco
import numpy as np
import pytest

from lomanip_sim.contact_forces import LimbForceMeter
from lomanip_sim.scenario import load_scenario
from lomanip_sim.simulator import Simulation


@pytest.fixture(scope="module")
def standing():
    sim = Simulation(load_scenario("s1_basket"))
    sim.run_for(1.0)
    return sim


def _robot_mass(model):
    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    return float(model.body_subtreemass[pelvis])


def test_feet_carry_the_weight(standing):
    f = LimbForceMeter(standing.model).measure(standing.data)
    weight = _robot_mass(standing.model) * 9.81
    total = f["left_foot"] + f["right_foot"]
    assert total[2] == pytest.approx(weight, rel=0.03)  # upwards ON the robot
    assert np.linalg.norm(total[:2]) < 0.03 * weight
    assert f["left_foot"][2] > 0.3 * weight and f["right_foot"][2] > 0.3 * weight  # both feet share it
    assert np.allclose(f["left_hand"], 0) and np.allclose(f["right_hand"], 0)


def test_pushed_sideways_feet_resist(standing):
    """A +y push on the pelvis while standing: friction at the feet pushes the robot back (-y)."""
    standing.apply_external_force("pelvis", (0.0, 60.0, 0.0), 0.3)
    standing.run_for(0.15)
    f = LimbForceMeter(standing.model).measure(standing.data)
    assert (f["left_foot"] + f["right_foot"])[1] < -20.0
