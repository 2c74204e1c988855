"""Options.dt_lift: finer knots in the stance phase in which an object leaves its support."""

from dataclasses import replace

import numpy as np

from lomanip_to.discretize import make_grid
from lomanip_to.fixtures import load_problem


def _lift_phase(prob) -> int:
    return next(i for i, p in enumerate(prob.phases)
                if any(mo.mode == "free" for mo in p.objects.values())
                and not any(mo.mode == "free" for mo in prob.phases[i - 1].objects.values()))


def test_lift_phase_gets_its_own_spacing(g1):
    prob = load_problem("case_lift_box", model=g1)
    i = _lift_phase(prob)
    ph = prob.phases[i]
    coarse = make_grid(prob)
    fine = make_grid(replace(prob, options=prob.options.replaced(dt_lift=0.05)))
    in_lift = lambda g: g.t[(g.phase == i) & (g.t < ph.end - 1e-9)]  # noqa: E731
    assert np.allclose(np.diff(np.append(in_lift(fine), ph.end)), 0.05)
    assert len(in_lift(fine)) > len(in_lift(coarse))
    # every other phase keeps its knots
    for g in (coarse, fine):
        assert np.array_equal(g.t[g.phase != i][g.t[g.phase != i] < ph.start], coarse.t[(coarse.phase != i) & (coarse.t < ph.start)])
    assert fine.K - coarse.K == len(in_lift(fine)) - len(in_lift(coarse))
