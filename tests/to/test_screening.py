"""Options.collision_screen_distance: collision rows far from their bound are left out of a stage."""

import dataclasses

import numpy as np
import pytest

from lomanip_to import screening, solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import ProblemError


def _window(g1, name="case_lift_box"):
    prob = load_problem(name, model=g1)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    return prob, data, win


def test_row_kinds_name_the_collision_rows(g1):
    _, _, win = _window(g1)
    kinds = screening.row_kinds(win)
    names = win.G.row_names()
    assert {names[i] for i in kinds.surrogate} == {f"c{i} homotopy surrogate" for i in range(len(win.st.obj_pairs))}
    assert [names[i] for i in kinds.surrogate_pair_row] == [f"c{i} collision" for i in range(len(win.st.obj_pairs))]
    assert "floor clearance" in {names[i] for i in kinds.distance}
    assert {names[i] for i in kinds.self_rows} == {f"self {a} {b}" for a, b in win.st.self_pairs}
    assert np.all(kinds.self_reach > 0)
    # nothing else is screenable: dynamics, contacts and torques always stay in
    screenable = {names[i] for i in np.concatenate([kinds.distance, kinds.surrogate, kinds.self_rows])}
    assert not any("dynamics" in n or "friction" in n or "torque" in n for n in screenable)


def _values(win, K, value=1.0):
    """Every row of every knot at ``value``, every slack at 0, every row bounded below by 0."""
    g = np.full(K * win.G.n, value)
    z = np.zeros((K + 1) * win.W.n)
    lbg = np.zeros(K * win.G.n)
    return g, z, lbg


def test_far_rows_by_distance(g1):
    _, data, win = _window(g1)
    kinds = screening.row_kinds(win)
    K, ng, nw = data.grid.K, win.G.n, win.W.n
    g, z, lbg = _values(win, K, value=1.0)       # every row 1 m (or F - 1 = 1) from its bound
    margin = np.zeros(K)
    far = screening.far_rows(kinds, win, K, g, z, lbg, margin, 0.1)
    n_sur = len(kinds.surrogate) * K
    assert far.rows.size == (len(kinds.distance) + len(kinds.self_rows)) * K + n_sur
    assert far.slacks.size == n_sur
    # knot 3: pair 0 comes within 5 cm -> its distance row and its surrogate row stay, its slack is free
    i_d, i_s = kinds.surrogate_pair_row[0], kinds.surrogate[0]
    g[3 * ng + i_d] = 0.05
    # knot 4: the floor row of one sphere is 2 cm up -> stays
    i_f = win.G["floor clearance"].start
    g[4 * ng + i_f] = 0.02
    # knot 5: a switched-off row is never screened (it is not in the stage at all)
    lbg[5 * ng + i_f] = -np.inf
    far = screening.far_rows(kinds, win, K, g, z, lbg, margin, 0.1)
    assert 3 * ng + i_d not in far.rows and 3 * ng + i_s not in far.rows
    assert 3 * nw + kinds.slack[0] not in far.slacks and 2 * nw + kinds.slack[0] in far.slacks
    assert 4 * ng + i_f not in far.rows and 5 * ng + i_f not in far.rows and 6 * ng + i_f in far.rows


def test_a_surrogate_row_is_screened_only_outside_the_surrogate(g1):
    """A sphere 50 cm from the box's faces may still be inside its surrogate (an ellipsoid through the
    corners): its surrogate row stays in while F < SURROGATE_FAR."""
    _, data, win = _window(g1)
    kinds = screening.row_kinds(win)
    K, ng = data.grid.K, win.G.n
    g, z, lbg = _values(win, K, value=0.5)
    g[2 * ng + kinds.surrogate[0]] = 0.2      # F = 1.2: inside the screening band of the surrogate
    far = screening.far_rows(kinds, win, K, g, z, lbg, np.zeros(K), 0.1)
    assert 2 * ng + kinds.surrogate[0] not in far.rows
    assert 2 * ng + kinds.surrogate_pair_row[0] in far.rows   # the exact distance is far


def test_self_rows_use_the_surface_gap(g1):
    """Self rows are |ci - cj|^2 - R^2 (m^2): screened by the gap between the sphere surfaces."""
    _, data, win = _window(g1)
    kinds = screening.row_kinds(win)
    K, ng = data.grid.K, win.G.n
    g, z, lbg = _values(win, K, value=5.0)
    R = kinds.self_reach[0]
    row = kinds.self_rows[0]
    g[row] = (R + 0.05) ** 2 - R ** 2          # knot 0: surfaces 5 cm apart
    g[ng + row] = (R + 0.3) ** 2 - R ** 2      # knot 1: 30 cm apart
    far = screening.far_rows(kinds, win, K, g, z, lbg, np.zeros(K), 0.1)
    assert row not in far.rows and ng + row in far.rows
    # the margin parameter adds to R: 30 cm apart with a 25 cm margin is 5 cm of gap
    margin = np.full(K, 0.25)
    g[ng + row] = (R + 0.3) ** 2 - (R + 0.25) ** 2
    far = screening.far_rows(kinds, win, K, g, z, lbg, margin, 0.1)
    assert ng + row not in far.rows


def test_violated_rows_counts_rows_that_do_not_hold(g1):
    _, data, win = _window(g1)
    kinds = screening.row_kinds(win)
    K, ng = data.grid.K, win.G.n
    g, z, lbg = _values(win, K, value=1.0)
    screen = screening.far_rows(kinds, win, K, g, z, lbg, np.zeros(K), 0.1)
    assert screening.violated_rows(screen, kinds, win, K, g, z, lbg, np.zeros(K), 0.1) == 0
    i_f = win.G["floor clearance"].start
    g[7 * ng + i_f] = 0.01     # nearer than the distance but holding: the result stands
    assert screening.violated_rows(screen, kinds, win, K, g, z, lbg, np.zeros(K), 0.1) == 0
    assert screening.violated_rows(screen, kinds, win, K, g, z, lbg, np.zeros(K), 0.1, fraction=0.5) == 1
    g[7 * ng + i_f] = -0.002   # past its bound: the stage must be solved again
    assert screening.violated_rows(screen, kinds, win, K, g, z, lbg, np.zeros(K), 0.1) == 1


def test_screened_lift_converges_with_fewer_rows(g1):
    """The light-box lift with a 10 cm screen: same physical checks, smaller NLPs."""
    prob = load_problem("case_lift_box", model=g1)
    screened = dataclasses.replace(prob, options=prob.options.replaced(collision_screen_distance=0.1))
    res = solver.solve(screened, g1)
    s = res.stats
    assert s.converged and res.success, s.status_message()
    for name, c in s.checks.items():
        assert c["ok"], f"{name}: {c}"
    assert all(st["screened_rows"] > 0 for st in s.stages if "screened_rows" in st)
    assert any("screened_rows" in st for st in s.stages)
    # the stages that were screened kept fewer rows than the same stage unscreened
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    full = {}
    for st_def, kind in zip(solver.homotopy_stages(prob.options, data), ("surrogate guide", "final")):
        lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *st_def)
        full[kind] = solver.active_rows(solver._vec(lbg), solver._vec(ubg)).size
    for st in s.stages:
        kind = "final" if st["stage"].startswith("final") else "surrogate guide"
        assert st["rows"] < full[kind]


@pytest.mark.parametrize("value", [-0.1, 1.5, float("nan")])
def test_bad_screen_distance_is_refused(g1, value):
    prob = load_problem("case_stand", model=g1)
    bad = dataclasses.replace(prob, options=prob.options.replaced(collision_screen_distance=value))
    with pytest.raises(ProblemError, match="collision_screen_distance"):
        solver.solve(bad, g1)
