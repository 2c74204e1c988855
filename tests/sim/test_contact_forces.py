"""contact_forces: the measured limb forces balance the robot's weight and point the right way."""

import mujoco
import numpy as np
import pytest

from lomanip_sim.contact_forces import LimbForceMeter, centre_of_pressure
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


def test_standing_centre_of_pressure_is_under_the_com(standing):
    """Standing still, each sole's centre of pressure lies on its sole and the two together lie
    under the CoM; a hand that touches nothing has none."""
    from lomanip_sim.robot_model import FOOT_BODIES, FOOT_CONTACT_POINTS, HAND_BODIES

    m, d = standing.model, standing.data
    points, forces = [], []
    for side in ("left", "right"):
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, FOOT_BODIES[side])
        cop, fn = centre_of_pressure(m, d, body)
        local = d.xmat[body].reshape(3, 3).T @ (cop - d.xpos[body])
        lo, hi = FOOT_CONTACT_POINTS.min(axis=0), FOOT_CONTACT_POINTS.max(axis=0)
        assert lo[0] - 1e-3 <= local[0] <= hi[0] + 1e-3 and lo[1] - 1e-3 <= local[1] <= hi[1] + 1e-3
        points.append(cop)
        forces.append(fn)
    both = (forces[0] * points[0] + forces[1] * points[1]) / sum(forces)
    pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    assert np.linalg.norm(both[:2] - d.subtree_com[pelvis][:2]) < 0.01
    assert sum(forces) == pytest.approx(_robot_mass(m) * 9.81, rel=0.05)
    hand = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, HAND_BODIES["left"])
    assert centre_of_pressure(m, d, hand) is None


def test_pushed_sideways_feet_resist(standing):
    """A +y push on the pelvis while standing: friction at the feet pushes the robot back (-y)."""
    standing.apply_external_force("pelvis", (0.0, 60.0, 0.0), 0.3)
    standing.run_for(0.15)
    f = LimbForceMeter(standing.model).measure(standing.data)
    assert (f["left_foot"] + f["right_foot"])[1] < -20.0
