"""Stance feet on the floor stay near the contact schedule's footholds (Options.foothold_radius)."""
from dataclasses import replace

import casadi as ca
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import SOLE_EDGE_MARGIN, ProblemData
from lomanip_to.fixtures import load_problem


def _with_footholds(prob, g1):
    """case_one_step with the footholds a planner would write: the initial soles, and the left sole
    15 cm ahead after its step."""
    limbs = g1.numeric(np.asarray(prob.initial_configuration, float))["limbs"]
    start = {f: np.asarray(limbs[f][0], float).ravel() for f in ("left_foot", "right_foot")}
    phases, stepped = [], False
    for ph in prob.phases:
        stepped = stepped or "left_foot" not in ph.contacts
        cs = {}
        for limb, c in ph.contacts.items():
            if limb in start:
                pos = start[limb] + (np.array([0.15, 0.0, 0.0]) if limb == "left_foot" and stepped else 0.0)
                c = replace(c, position=(float(pos[0]), float(pos[1]), 0.0))
            cs[limb] = c
        phases.append(replace(ph, contacts=cs))
    return replace(prob, phases=phases)


def _filled(g1, radius):
    prob = _with_footholds(load_problem("case_one_step", model=g1), g1)
    prob.options = prob.options.replaced(foothold_radius=radius)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    return data, win, data.fill(win, 2.0, True, True, True)


def _floor_stance_knots(data, foot):
    return [k for k in range(data.grid.K) if data.contact(k, foot) is not None
            and data.contact(k, foot).object_id == "floor" and data.contact(k, foot).position is not None]


def test_patch_is_a_square_round_each_foothold(g1):
    data, win, (_, _, lbg, ubg, Pm, _) = _filled(g1, 0.06)
    for foot in ("left_foot", "right_foot"):
        knots = _floor_stance_knots(data, foot)
        assert knots
        row = win.G[f"{foot} inside contact patch"]
        for k in knots:
            pos = np.asarray(data.contact(k, foot).position, float)
            np.testing.assert_allclose(Pm[win.P[f"{foot}_patch"], k], [pos[0], pos[1], 1.0, 0.0])
            np.testing.assert_allclose(ubg[row, k], 0.06)
            np.testing.assert_allclose(lbg[row, k], -0.06)
    assert SOLE_EDGE_MARGIN > 0


def test_radius_zero_leaves_the_floor_unbounded(g1):
    data, win, (_, _, lbg, ubg, _, _) = _filled(g1, 0.0)
    row = win.G["left_foot inside contact patch"]
    for k in _floor_stance_knots(data, "left_foot"):
        assert np.all(np.isinf(ubg[row, k])) and np.all(np.isinf(lbg[row, k]))


def test_warm_start_stands_inside_the_squares_and_a_far_foot_is_outside(g1):
    data, win, (_, _, lbg, ubg, Pm, W0) = _filled(g1, 0.06)
    g = ca.Function("g", [win.a, win.b, win.p], [win.g])
    row = win.G["right_foot inside contact patch"]
    knots = _floor_stance_knots(data, "right_foot")
    for k in knots:
        val = np.array(g(W0[:, k], W0[:, k + 1], Pm[:, k])).ravel()[row]
        assert np.all(val <= ubg[row, k] + 1e-6) and np.all(val >= lbg[row, k] - 1e-6), (k, val)
    k = knots[-1]
    a = W0[:, k].copy()
    a[win.W["x"].start] += 0.15  # the whole robot (pelvis x) 15 cm forward: the sole leaves its square
    val = np.array(g(a, W0[:, k + 1], Pm[:, k])).ravel()[row]
    assert val[0] > ubg[row, k][0]
