"""An object set down on another object's top rests on it, its centre over it; Options.placement_tolerance."""
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import SUPPORT_EDGE_MARGIN, ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import STANCE, ContactPhase, ProblemError, validate_problem


def _set_down(g1, z: float, **options):
    """case_lift_box with the box set down (left where it is) for 0.4 s after the lift at height z."""
    prob = load_problem("case_lift_box", model=g1, options=options)
    last = prob.phases[-1]
    feet = {f: c for f, c in last.contacts.items() if f.endswith("_foot")}
    goal = replace(prob.placement_goals[0], position=(*prob.placement_goals[0].position[:2], z), time=last.end)
    return replace(prob, phases=[*prob.phases, ContactPhase(last.end, last.end + 0.4, STANCE, 0, contacts=feet)],
                   placement_goals=[goal])


def _rows_at(data, name, k):
    win, _ = solver.get_window(data.model, data.structure)
    lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *solver.homotopy_stages(data.prob.options, data)[-1])
    idx = win.G[name]
    g = ca.Function("g", [win.a, win.b, win.p], [win.g[idx]])
    return np.asarray(g(W0[:, k], W0[:, k + 1], Pm[:, k])).ravel(), lbg[idx, k], ubg[idx, k]


def test_s2s_box_is_set_down_over_the_trolleys_deck(g1):
    data = ProblemData(load_problem("s2_trolley", model=g1), g1)
    placed = [k for k in range(data.grid.K) if data.support_under(k, "box") is not None]
    assert len(placed) == 1 and data.grid.t[placed[0]] == pytest.approx(7.4)
    sid, pi = data.support_under(placed[0], "box")
    assert sid == "trolley"
    half = data.prob.object("trolley").primitives[pi].half_extents()
    assert np.allclose(data._support_bounds(placed[0], "box"), half[:2] - SUPPORT_EDGE_MARGIN)
    # the trolley itself rolls on the floor: unbounded
    assert all(data.support_under(k, "trolley") is None for k in range(data.grid.K))


def test_the_row_is_the_centre_in_the_supports_frame_and_bounded_only_where_resting(g1):
    data = ProblemData(_set_down(g1, 0.77), g1)
    k_set = next(k for k in range(data.grid.K) if data.support_under(k, "box") is not None)
    assert data.support_under(k_set, "box") == ("table", 0)
    value, lo, hi = _rows_at(data, "o0 over its support", k_set)
    table = data.prob.object("table")
    centre = np.asarray(data.obj_nom["box"][k_set][:2]) - np.asarray(table.position[:2])
    assert np.allclose(value, centre, atol=1e-9)
    half = table.primitives[0].half_extents()[:2]
    assert np.allclose(hi, half - np.minimum(SUPPORT_EDGE_MARGIN, 0.25 * half)) and np.allclose(lo, -hi)
    _, lo, hi = _rows_at(data, "o0 over its support", k_set - 1)  # still carried
    assert np.all(lo == -np.inf) and np.all(hi == np.inf)


def test_an_object_set_down_in_mid_air_is_refused(g1):
    with pytest.raises(ProblemError, match="set down at t=2.40 s .* no object's top under it"):
        ProblemData(_set_down(g1, 0.87), g1)


def test_an_object_set_down_on_the_floor_has_no_row(g1):
    prob = _set_down(g1, 0.77)
    box = prob.object("box")
    prob = replace(prob, placement_goals=[replace(prob.placement_goals[0], position=(0.27, 0.6, -box.bottom_z()))])
    data = ProblemData(prob, g1)
    assert all(data.support_under(k, "box") is None for k in range(data.grid.K))


def test_placement_tolerance_bounds_the_goal_knot_only(g1):
    data = ProblemData(_set_down(g1, 0.77, placement_tolerance=0.04), g1)
    k_goal = int(np.argmin(np.abs(data.grid.t - data.prob.placement_goals[0].time)))
    value, lo, hi = _rows_at(data, "o0 at its placement goal", k_goal)
    assert np.allclose(lo, -0.04) and np.allclose(hi, 0.04)
    assert np.allclose(value, data.obj_nom["box"][k_goal][:2] - np.asarray(data.prob.placement_goals[0].position[:2]))
    _, lo, hi = _rows_at(data, "o0 at its placement goal", k_goal - 1)
    assert np.all(lo == -np.inf)
    # off by default: the goal is a cost only
    _, lo, _ = _rows_at(ProblemData(_set_down(g1, 0.77), g1), "o0 at its placement goal", k_goal)
    assert np.all(lo == -np.inf)
    with pytest.raises(ProblemError, match="placement_tolerance"):
        validate_problem(_set_down(g1, 0.77, placement_tolerance=-0.1), g1)


def test_the_check_measures_how_far_a_set_down_centre_is_past_the_tops_edge(g1):
    from types import SimpleNamespace

    from lomanip_to.checks import off_support

    data = ProblemData(_set_down(g1, 0.77), g1)
    k_set = next(k for k in range(data.grid.K) if data.support_under(k, "box") is not None)
    table = data.prob.object("table")
    edge = table.position[0] + table.primitives[0].half_extents()[0]
    poses = np.tile(data.obj_nom["box"][k_set], (data.grid.K, 1))
    res = SimpleNamespace(object_pose_knots={"box": poses}, t_knots=data.grid.t)
    assert off_support(data, res)[0] < 0
    poses[:, 0] = edge + 0.03
    v, oid, t = off_support(data, res)
    assert (oid, t) == ("box", pytest.approx(data.grid.t[k_set])) and v == pytest.approx(0.03)


def test_an_object_set_down_rests_on_the_top_not_at_its_nominals_height(g1):
    data = ProblemData(_set_down(g1, 0.785), g1)  # the goal 1.5 cm above the table's top
    k_set = next(k for k in range(data.grid.K) if data.support_under(k, "box") is not None)
    win, _ = solver.get_window(g1, data.structure)
    Pm = data.fill(win, *solver.homotopy_stages(data.prob.options, data)[-1])[4]
    table, box = data.prob.object("table"), data.prob.object("box")
    assert Pm[win.P["o0_zrest"], k_set][0] == pytest.approx(table.position[2] + table.top_z() - box.bottom_z())
