"""Options.dt_reach: finer knots in the stance phase at whose end a hand makes a new contact."""

from dataclasses import replace

import numpy as np

from lomanip_to.discretize import make_grid, reaches
from lomanip_to.fixtures import load_problem
from lomanip_to.solver import rest_points


def _reach_phase(prob) -> int:
    return next(i for i in range(len(prob.phases)) if reaches(prob.phases, i))


def test_reach_phase_gets_its_own_spacing(g1):
    prob = load_problem("case_lift_box", model=g1)
    i = _reach_phase(prob)
    ph, nxt = prob.phases[i], prob.phases[i + 1]
    assert any(h.endswith("hand") and h not in ph.contacts for h in nxt.contacts)
    coarse = make_grid(prob)
    fine = make_grid(replace(prob, options=prob.options.replaced(dt_reach=0.05)))
    in_reach = lambda g: g.t[g.phase == i]  # noqa: E731
    assert np.allclose(np.diff(np.append(in_reach(fine), ph.end)), 0.05)
    assert len(in_reach(fine)) > len(in_reach(coarse))
    # every other phase keeps its knots
    assert np.array_equal(fine.t[fine.phase != i], coarse.t[coarse.phase != i])


def test_no_reach_across_a_subtask_boundary(g1):
    prob = load_problem("case_lift_box", model=g1)
    i = _reach_phase(prob)
    phases = list(prob.phases)
    phases[i + 1] = replace(phases[i + 1], subtask_index=phases[i].subtask_index + 1)
    assert not reaches(phases, i)


def test_walking_and_the_last_phase_are_not_reaches(g1):
    prob = load_problem("case_one_step", model=g1)
    assert not any(reaches(prob.phases, i) for i in range(len(prob.phases)))
    assert not reaches(prob.phases, len(prob.phases) - 1)


def test_no_rest_cut_between_a_reach_and_its_grasp(g1):
    """A segment must end after the grasp the reach leads to, or its grid would not be the whole one's."""
    prob = load_problem("s1_basket", model=g1)
    reach_ends = {ph.end for j, ph in enumerate(prob.phases) if reaches(prob.phases, j)}
    off = set(rest_points(replace(prob, options=prob.options.replaced(rest_segments=True))))
    on = set(rest_points(replace(prob, options=prob.options.replaced(dt_reach=0.1, rest_segments=True))))
    assert off & reach_ends  # without the reach's spacing the grasp is a rest point
    assert not on & reach_ends
