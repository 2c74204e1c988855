"""standing: the torque-controlled G1 stands 60 s in S1 and S2 and rejects pelvis pushes.

No base freezing, welds or qpos writes: the Simulation only sets actuator torques.
"""

import time

import numpy as np
import pytest

from lomanip_sim.scenario import load_scenario
from lomanip_sim.simulator import Simulation

PUSH_DIRECTIONS = {"forward": (1, 0, 0), "backward": (-1, 0, 0), "left": (0, 1, 0), "right": (0, -1, 0)}


@pytest.fixture(scope="module")
def sim_s1():
    return Simulation(load_scenario("s1_basket"))


@pytest.mark.parametrize("scenario", ["s1_basket", "s2_trolley"])
def test_stands_60s(scenario):
    sim = Simulation(load_scenario(scenario))
    heights = []
    t0 = time.perf_counter()
    for _ in range(60):
        sim.run_for(1.0)
        heights.append(sim.pelvis_height())
        assert not sim.has_fallen(), f"fell at t={sim.time:.1f}s"
    wall = time.perf_counter() - t0
    print(f"\n{scenario}: 60 s simulated in {wall:.2f} s wall, real-time factor {60.0 / wall:.1f}, "
          f"pelvis height {min(heights):.4f}..{max(heights):.4f} m")
    assert sim.time == pytest.approx(60.0, abs=0.01)
    assert np.all(np.abs(np.array(heights) - 0.79) < 0.02)
    _, _, tau = sim.joint_arrays()
    assert np.all(np.abs(tau) <= sim.world.torque_limits + 1e-9)
    pos, _ = sim.base_pose()
    assert np.linalg.norm(pos[:2]) < 0.05  # no drift


def _survives(sim: Simulation, direction, force: float, duration: float = 0.2, settle: float = 3.0) -> bool:
    sim.reset()
    sim.run_for(0.3)
    sim.apply_external_force("pelvis", np.asarray(direction, float) * force, duration)
    for _ in range(int(settle / 0.1)):
        sim.run_for(0.1)
        if sim.has_fallen():
            return False
    return sim.pelvis_height() > 0.75


@pytest.mark.parametrize("direction", list(PUSH_DIRECTIONS))
def test_rejects_40N_push(sim_s1, direction):
    """40 N on the pelvis for 0.2 s (8 N s, about 0.24 m/s of CoM velocity) in every direction."""
    assert _survives(sim_s1, PUSH_DIRECTIONS[direction], 40.0)


@pytest.mark.slow
def test_largest_survivable_push(sim_s1):
    """Sweeps the force (0.2 s pushes) per direction; prints the largest survived."""
    found = {}
    for name, d in PUSH_DIRECTIONS.items():
        best = 0.0
        for f in range(40, 301, 20):
            if not _survives(sim_s1, d, float(f)):
                break
            best = float(f)
        found[name] = best
    print("\nlargest survived 0.2 s pelvis push (N):", found)
    assert min(found.values()) >= 40.0
