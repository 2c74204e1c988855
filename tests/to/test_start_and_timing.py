"""A slightly tilted measured start stays feasible, and each solve stage reports where its time went."""
from dataclasses import replace

import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def _tilted(g1, roll=0.01):
    prob = load_problem("case_stand", model=g1)
    x0 = np.array(prob.initial_configuration if prob.initial_configuration is not None else np.zeros(35), float)
    x0[3] = roll  # base roll: both soles tilt, knot 0 is fixed there
    return replace(prob, initial_configuration=tuple(x0))


def test_knot0_tilt_rows_admit_the_given_start(g1):
    data = ProblemData(_tilted(g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    r = win.G["left_foot orientation aligned with surface"]
    tilt = data._initial_tilt("left_foot")
    assert abs(tilt[1]) > 1e-3  # the roll shows up in the rows
    assert np.all(lbg[r, 0] <= tilt + 1e-12) and np.all(tilt - 1e-12 <= ubg[r, 0])
    assert np.all(lbg[r, 1:] == 0) and np.all(ubg[r, 1:] == 0)  # later knots: level sole required


def test_stage_timing_split(g1):
    res = solver.solve(load_problem("case_stand", model=g1), g1)
    assert res.stats.stages
    for st in res.stats.stages:
        t = st["timing"]
        assert 0 < t["eval"] <= t["wall"] + 1e-6
        assert t["calls"]["nlp_hess_l"] >= 1
        assert abs(t["wall"] - t["eval"] - t["callback"] - t["rest"]) < 1e-6 or t["rest"] == 0.0


def test_floor_clearance_rows_for_every_sphere(g1):
    data = ProblemData(load_problem("case_one_step", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    for stage in solver.homotopy_stages(data.prob.options):
        _, _, lbg, ubg, _, _ = data.fill(win, *stage)
        r = win.G["floor clearance"]
        assert r.stop - r.start == len(g1.spheres)
        assert np.all(lbg[r] == 0) and np.all(np.isinf(ubg[r]))
