"""Options.arm_body_self_pairs: each arm also keeps clear of the torso, its own upper thigh and hip
front (S1's step onto the box had the upper arm in the torso and the forearm in the thigh, unchecked)."""
import numpy as np

from lomanip_to.discretize import ProblemData, self_pairs
from lomanip_to.fixtures import load_problem


def _named(g1, pairs):
    return {(g1.spheres[a].name, g1.spheres[b].name) for a, b in pairs}


def test_the_arm_pairs_add_to_the_default_ones(g1):
    base, more = _named(g1, self_pairs(g1)), _named(g1, self_pairs(g1, arm_body=True))
    assert base < more
    for side in ("left", "right"):
        assert (f"{side}_upper_arm_0", "torso_0") in more - base
        assert (f"{side}_forearm_0", f"{side}_thigh_0") in more - base
        assert (f"{side}_hand_tip", f"{side}_hip_front") in more - base
    both = self_pairs(g1, True, True)
    assert len(set(both)) == len(both)   # with hand_body_self_pairs too, no pair twice
    assert set(self_pairs(g1, True)) | set(self_pairs(g1, arm_body=True)) == set(both)


def test_the_problem_takes_them_and_starts_clear_of_them(g1):
    prob = load_problem("case_stand", model=g1)
    prob.options = prob.options.replaced(arm_body_self_pairs=True)
    data = ProblemData(prob, g1)
    assert data.structure.self_pairs == self_pairs(g1, arm_body=True)
    # standing, arms down: every new row holds (the upper arm is 2.6 cm off the torso sphere)
    cs = g1.numeric(np.asarray(data.x_guess[0], float))["spheres"]
    for i, j in set(self_pairs(g1, arm_body=True)) - set(self_pairs(g1)):
        gap = np.linalg.norm(cs[i] - cs[j]) - g1.spheres[i].radius - g1.spheres[j].radius
        assert gap > 0.0, f"{g1.spheres[i].name} - {g1.spheres[j].name}: {gap * 100:.1f} cm"


def test_the_arm_rows_hold_only_while_that_hand_is_free(g1):
    from lomanip_to import solver
    from lomanip_to.discretize import arm_body_pairs

    prob = load_problem("case_lift_box", model=g1)
    prob.options = prob.options.replaced(arm_body_self_pairs=True)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, _, _, _ = data.fill(win, 6.0, True, False, False)  # the final (hard) stage's bounds
    holding = [k for k in range(data.grid.K) if data.contact(k, "left_hand") is not None]
    free = [k for k in range(data.grid.K) if data.contact(k, "left_hand") is None]
    assert holding and free
    for (a, b), side in arm_body_pairs(g1).items():
        row = lbg[win.G[f"self {a} {b}"]]
        hand_on = [k for k in range(data.grid.K) if data.contact(k, f"{side}_hand") is not None]
        assert np.all(row[:, hand_on] == -np.inf) and np.all(np.delete(row, hand_on, axis=1) == 0.0)
    # the default pairs hold at every knot
    i, j = self_pairs(g1)[0]
    assert np.all(lbg[win.G[f"self {i} {j}"]] == 0.0)
