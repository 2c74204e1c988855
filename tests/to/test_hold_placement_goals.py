"""Options.hold_placement_goals: an object still held after its goal's time is held at the goal."""

import dataclasses

import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def _goal_weights(g1, prob, oid: str) -> np.ndarray:
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, _, _, P, _ = data.fill(win, *solver.homotopy_stages(prob.options, data)[-1])
    return data, P[win.P[f"o{data.midx[oid]}_w_goal"]].ravel()


def test_goal_cost_covers_the_hold_after_the_goal(g1):
    """S1's fixture lifts the basket to its goal at 17.8 s and holds it to 18.2 s."""
    prob = load_problem("s1_basket", model=g1)
    goal = next(g for g in prob.placement_goals if g.object_id == "basket")
    data, off = _goal_weights(g1, prob, "basket")
    k_goal, K = data.goal_knot(goal), data.grid.K
    held = [k for k in range(k_goal + 1, K - 1) if data.obj_mode(k, "basket") == "free"]
    assert held, "the fixture holds the basket between its goal and the end"
    assert np.all(off[held] == 0.0) and off[k_goal] == goal.weight and off[K - 1] == goal.weight
    on_prob = dataclasses.replace(prob, options=prob.options.replaced(hold_placement_goals=True))
    _, on = _goal_weights(g1, on_prob, "basket")
    assert np.all(on[held] == goal.weight)
    # before the goal's time nothing changes
    assert np.array_equal(on[:k_goal], off[:k_goal])


def test_a_set_down_object_is_not_held(g1):
    """The box is put down at its goal (supported after it): the option adds no cost to it."""
    prob = load_problem("s1_basket", model=g1)
    on_prob = dataclasses.replace(prob, options=prob.options.replaced(hold_placement_goals=True))
    _, off = _goal_weights(g1, prob, "box")
    _, on = _goal_weights(g1, on_prob, "box")
    assert np.array_equal(on, off)
