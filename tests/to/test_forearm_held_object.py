"""Options.forearm_clear_of_held_object: the forearm spheres stay out of an object their hand holds
(within HELD_OBJECT_FOREARM_DEPTH, the rubber hand's inner face being that far from the TO's hand point)."""
import numpy as np
import pytest

from lomanip_to import checks, solver
from lomanip_to.discretize import HELD_OBJECT_FOREARM_DEPTH, ProblemData, obj_prims_world
from lomanip_to.fixtures import load_problem


def _held_knot(data):
    return next(k for k in range(data.grid.K) if data.contact(k, "left_hand") is not None)


def _sphere(g1, name):
    return next(i for i, s in enumerate(g1.spheres) if s.name == name)


@pytest.mark.parametrize("on", [False, True])
def test_the_forearm_pair_is_on_only_with_the_option(g1, on):
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(forearm_clear_of_held_object=on)
    data = ProblemData(prob, g1)
    k = _held_knot(data)
    wrist, hand = _sphere(g1, "left_wrist"), _sphere(g1, "left_hand")
    assert data._pair_enabled(k, wrist, "box") is on
    assert data._pair_enabled(k, hand, "box") is False  # the hand itself touches the box
    if on:
        assert data._clearance(wrist, k, "box") == -HELD_OBJECT_FOREARM_DEPTH
        assert not data._surrogate_on(k, wrist, "box")
    # before the grasp the forearm keeps the usual rule (on, no allowance, surrogate on)
    assert data._pair_enabled(0, wrist, "box") and data._clearance(wrist, 0, "box") == 0.0
    assert data._surrogate_on(0, wrist, "box")


@pytest.mark.parametrize("on", [False, True])
def test_the_held_knots_get_a_collision_row_for_each_forearm_sphere(g1, on):
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(forearm_clear_of_held_object=on)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, _, _, _ = data.fill(win, 6.0, True, False, False)
    k = _held_knot(data)
    wrist = _sphere(g1, "left_wrist")
    i = next(i for i, (s, (oid, _)) in enumerate(data.pairs) if s == wrist and oid == "box")
    row = lbg[win.G[f"c{i} collision"], k]
    assert np.all(row == (-HELD_OBJECT_FOREARM_DEPTH if on else -np.inf))


def test_a_lift_with_the_option_keeps_the_wrists_within_the_allowance(g1):
    """case_lift_box with the option converges; the wrist spheres stay within the allowance of the
    held box and the physical checks (which count the allowance) see no penetration."""
    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(forearm_clear_of_held_object=True)
    res = solver.solve(prob, g1)
    assert res.stats.converged, res.stats.status_message()
    data = ProblemData(prob, g1)
    wrists = [_sphere(g1, "left_wrist"), _sphere(g1, "right_wrist")]
    box = next(o for o in prob.objects if o.id == "box")
    worst = np.inf
    for k in range(len(res.t_knots)):
        if data.contact(k, "left_hand") is None:
            continue
        cs = g1.numeric(res.x_knots[k])["spheres"]
        pose = res.object_pose_knots["box"][k]
        for s in wrists:
            for c, R, he in obj_prims_world(box, pose[:3], pose[3:]):
                worst = min(worst, checks.sphere_box_distance(cs[s], c, R, he, g1.spheres[s].radius))
    assert worst >= -HELD_OBJECT_FOREARM_DEPTH - 2e-3
    _, deepest, _ = checks.penetration_per_knot(g1, data, res)
    assert deepest <= 5e-3
    assert res.stats.checks["penetration"]["held_object_forearm"] <= HELD_OBJECT_FOREARM_DEPTH + 2e-3


def test_without_the_option_the_checks_report_the_wrists_inside_the_held_box(g1):
    """The default plan of case_lift_box holds the box with the wrist spheres 3 cm inside it; the
    checks report it (not gated)."""
    res = solver.solve(load_problem("case_lift_box", model=g1), g1)
    pen = res.stats.checks["penetration"]
    assert pen["held_object_forearm"] > 0.01
    assert "wrist vs box" in pen["held_object_forearm_where"] or "forearm" in pen["held_object_forearm_where"]
