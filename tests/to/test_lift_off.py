"""Lift-off of a resting object: its support only holds it, the hands alone accelerate it."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def test_first_free_knot_after_a_support_is_at_rest(g1):
    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, _, _, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    j = data.midx["box"]
    modes = [data.obj_mode(k, "box") for k in range(data.grid.K)]
    lift = [k for k in range(1, data.grid.K) if modes[k] == "free" and modes[k - 1] == "supported"]
    assert lift, f"S1 lifts the box from the floor: {modes}"
    v = win.W[f"o{j}_vel"]
    for k in lift:
        # semi-implicit integration: v_k = v_k-1 + dt F_k-1 / m, p_k = p_k-1 + dt v_k. With v_k = 0
        # the support's force at k-1 only balances gravity and the hands; it cannot launch the box.
        assert np.all(lbw[v, k] == 0) and np.all(ubw[v, k] == 0)
        # and the carried knots after it may move
        assert np.any(ubw[v, k + 1] > 0)


def test_a_carried_object_stays_nearly_level(g1):
    from lomanip_to.discretize import CARRY_TILT

    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, _, _, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    pose = win.W[f"o{data.midx['box']}_pose"]
    free = [k for k in range(1, data.grid.K) if data.obj_mode(k, "box") == "free"]
    assert free
    for k in free:
        np.testing.assert_array_equal(ubw[pose, k][3:5], [CARRY_TILT, CARRY_TILT])
        np.testing.assert_array_equal(lbw[pose, k][3:5], [-CARRY_TILT, -CARRY_TILT])
        assert ubw[pose, k][5] == np.inf  # yaw is the carrier's to choose
    resting = [k for k in range(1, data.grid.K) if data.obj_mode(k, "box") == "fixed"]
    assert resting and all(ubw[pose, k][3] == np.inf for k in resting)


def test_objects_end_at_rest_like_the_robot(g1):
    """A subtask segment ends where the next starts at rest: every moving object's velocity is 0 at
    the last knot, here a segment cut in the middle of S2's push, the trolley still rolling (a
    supported box still sliding there broke its dynamics row once stitched)."""
    prob = load_problem("s2_trolley", model=g1)
    ends = [ph.end for ph in prob.phases if ph.objects.get("trolley") is not None and ph.objects["trolley"].mode == "rolling"]
    assert len(ends) > 1
    seg = solver.segment_problem(prob, 0.0, ends[0], prob.initial_configuration,
                                 {o.id: np.concatenate([np.asarray(o.position, float), o.rpy()]) for o in prob.objects})
    data = ProblemData(seg, g1, moving=ProblemData(prob, g1).moving)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, _, _, _, _ = data.fill(win, *solver.homotopy_stages(seg.options)[-1])
    N = data.grid.K - 1
    j = data.midx["trolley"]
    assert data.obj_mode(N, "trolley") == "rolling"
    v = win.W[f"o{j}_vel"]
    assert np.all(lbw[v, N] == 0) and np.all(ubw[v, N] == 0)
    assert np.any(ubw[v, N - 1] > 0)   # it may roll before that


def test_the_knots_after_a_lift_off_start_gently(g1):
    """The first LIFT_OFF_KNOTS free knots after the one at rest have their speed and turn rates
    bounded by n x LIFT_OFF_SPEED / LIFT_OFF_TURN_RATE; the carry after them is not."""
    from lomanip_to.discretize import LIFT_OFF_KNOTS, LIFT_OFF_SPEED, LIFT_OFF_TURN_RATE

    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, _, _, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    v = win.W[f"o{data.midx['box']}_vel"]
    modes = [data.obj_mode(k, "box") for k in range(data.grid.K)]
    rest = next(k for k in range(1, data.grid.K) if modes[k] == "free" and modes[k - 1] == "supported")
    assert np.all(ubw[v, rest] == 0)
    for n in range(1, LIFT_OFF_KNOTS + 1):
        lim = n * np.array([LIFT_OFF_SPEED] * 3 + [LIFT_OFF_TURN_RATE] * 3)
        np.testing.assert_allclose(ubw[v, rest + n], lim)
        np.testing.assert_allclose(lbw[v, rest + n], -lim)
    assert modes[rest + LIFT_OFF_KNOTS + 1] == "free"
    assert np.all(ubw[v, rest + LIFT_OFF_KNOTS + 1] == 3.0)


def _lift_off_bounds(g1, **options):
    from dataclasses import replace

    prob = load_problem("s2_trolley", model=g1)
    prob = replace(prob, options=replace(prob.options, **options))
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, _, _, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options, data)[-1])
    modes = [data.obj_mode(k, "box") for k in range(data.grid.K)]
    lift = [k for k in range(1, data.grid.K) if modes[k] == "free" and modes[k - 1] == "fixed"]
    assert lift, f"S2 lifts the box off the table, where it rests untouched: {modes}"
    v = win.W[f"o{data.midx['box']}_vel"]
    return [(lbw[v, k + n][:3], ubw[v, k + n][:3]) for k in lift for n in (1, 2)]


def test_a_box_lifted_off_a_table_starts_gently_too(g1):
    """S2's box rests untouched ("fixed") on the table until the hands lift it: the knots after its
    lift-off get the gentle start's speed bounds as a box lifted off the floor does."""
    from lomanip_to.discretize import LIFT_OFF_SPEED

    (lo1, hi1), (lo2, hi2) = _lift_off_bounds(g1)[:2]
    np.testing.assert_allclose(hi1, LIFT_OFF_SPEED)
    np.testing.assert_allclose(lo2, -2 * LIFT_OFF_SPEED)


def test_lift_off_vertical_rises_before_moving_sideways(g1):
    (lo1, hi1), (lo2, hi2) = _lift_off_bounds(g1, lift_off_vertical=0.1)[:2]
    for lo, hi in ((lo1, hi1), (lo2, hi2)):
        np.testing.assert_allclose(lo[:2], -0.1)
        np.testing.assert_allclose(hi[:2], 0.1)
        assert lo[2] == 0.1 and hi[2] >= 0.25
