"""TO fixture cases solved once per test process and turned into executable trajectories/worlds.

Why: test_wbc, test_execution and test_media all execute real TO results (not hand-made motions);
solving case_stand/case_one_step takes 1-5 s, so each is solved once per pytest process.
"""

from __future__ import annotations

import functools

from lomanip_sim import scene_world
from lomanip_sim.simulator import Simulation
from lomanip_sim.trajectory import Trajectory, from_to_result


@functools.lru_cache(maxsize=None)
def solved(name: str, options: tuple = ()):
    """(densified TOResult, Problem) of the lomanip_to fixture ``name``; ``options``: (field, value)
    pairs of TO Options over the fixture's."""
    from lomanip_to import fixtures, solver

    prob = fixtures.load_problem(name)
    if options:
        prob.options = prob.options.replaced(**dict(options))
    res = solver.solve(prob)
    res.densify()
    return res, prob


def trajectory(name: str, options: tuple = ()) -> Trajectory:
    res, prob = solved(name, options)
    return from_to_result(res, prob.phases, scenario=name)


def simulation(name: str, options: tuple = ()) -> tuple[Simulation, Trajectory]:
    """A fresh Simulation of the plan's scene with the robot at the plan's first point."""
    _res, prob = solved(name, options)
    tr = trajectory(name, options)
    world = scene_world.build_scene_world(scene_world.objects_from_to_problem(prob), robot_qpos=tr.qpos(0))
    return Simulation(world), tr
