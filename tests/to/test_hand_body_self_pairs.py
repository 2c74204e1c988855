"""Options.hand_body_self_pairs: the hands and wrists also keep clear of the other side's hip and
thigh, the torso's lower front and their own shin (S1's plans parked a hand there, unchecked)."""
import numpy as np

from lomanip_to.discretize import ProblemData, self_pairs
from lomanip_to.fixtures import load_problem


def _named(g1, pairs):
    return {(g1.spheres[a].name, g1.spheres[b].name) for a, b in pairs}


def test_the_extra_pairs_add_to_the_default_ones(g1):
    base, more = _named(g1, self_pairs(g1)), _named(g1, self_pairs(g1, True))
    assert base < more
    for side, other in (("left", "right"), ("right", "left")):
        assert (f"{side}_hand", f"{other}_hip_roll") in more - base
        assert (f"{side}_wrist", f"{side}_shin_0") in more - base
        assert (f"{side}_hand", "torso_low_1") in more - base
    assert len(set(self_pairs(g1, True))) == len(self_pairs(g1, True))   # no pair twice


def test_the_problem_takes_them_and_starts_clear_of_them(g1):
    prob = load_problem("case_stand", model=g1)
    assert ProblemData(prob, g1).structure.self_pairs == self_pairs(g1)
    prob.options = prob.options.replaced(hand_body_self_pairs=True)
    data = ProblemData(prob, g1)
    assert data.structure.self_pairs == self_pairs(g1, True)
    # the standing start keeps the left hand clear of the right hip (its row holds at the start)
    names = [s.name for s in g1.spheres]
    x = np.asarray(data.x_guess[0], float)
    cs = g1.numeric(x)["spheres"]
    i, j = names.index("left_hand"), names.index("right_hip_roll")
    r = g1.spheres[i].radius + g1.spheres[j].radius
    assert np.linalg.norm(cs[i] - cs[j]) > r
    assert (i, j) in data.structure.self_pairs
