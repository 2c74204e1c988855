"""Options.segment_moving_objects: each subtask segment carries only the objects it moves or touches,
and the stitch puts the others back on the whole horizon's window, standing still."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def _segments(g1, prob):
    whole = ProblemData(prob, g1)
    poses = solver._initial_poses(prob)
    out = []
    for t0, t1 in solver.segments(prob):
        sp = solver.segment_problem(prob, t0, t1, prob.initial_configuration, poses)
        moving = solver.segment_moving(whole.moving, sp)
        out.append((sp, moving))
    return whole, out


def test_s1_moves_the_basket_in_its_last_segment_only(g1):
    prob = load_problem("s1_basket", model=g1)
    assert prob.options.segment_moving_objects
    whole, segs = _segments(g1, prob)
    assert whole.moving == ["box", "basket"]
    # the walk to the box ends with the hands on it; the carry moves it; the last subtask lifts the basket
    assert [m for _, m in segs] == [["box"], ["box"], ["basket"]]


def test_a_standing_object_is_filled_in_as_fixed(g1):
    """The last segment's window has the basket alone; on the whole window the basket's blocks come
    from it and the box holds the pose the segment had it at, with zero velocity and support forces."""
    prob = load_problem("s1_basket", model=g1)
    whole, segs = _segments(g1, prob)
    sp, moving = segs[-1]
    box_at = np.array([1.41, 1.0, 0.15, 0.0, 0.0, 0.02])   # where an earlier segment set it down
    poses = {**solver._initial_poses(prob), "box": box_at}
    sp = solver.segment_problem(prob, *solver.segments(prob)[-1], prob.initial_configuration, poses)
    env = [e for e in whole.env_pairs if e[0] in moving]
    sd = ProblemData(sp, g1, moving=moving, pairs=whole.pairs, stand=whole.x_init, env_pairs=env)
    assert sd.structure.n_obj == 1 and whole.structure.n_obj == 2
    assert sd.structure.env_pairs == len(env) < whole.structure.env_pairs
    swin, _ = solver.get_window(g1, sd.structure)
    win, _ = solver.get_window(g1, whole.structure)
    rng = np.random.default_rng(0)
    Zs = rng.normal(size=(sd.grid.K, swin.W.n))
    Z = solver._onto_window(win, whole, swin, sd, Zs, primal=True)
    assert Z.shape == (sd.grid.K, win.W.n)
    jb = whole.midx["basket"]
    np.testing.assert_array_equal(Z[:, win.W[f"o{jb}_pose"]], Zs[:, swin.W["o0_pose"]])
    np.testing.assert_array_equal(Z[:, win.W[f"o{jb}_us"]], Zs[:, swin.W["o0_us"]])
    jx = whole.midx["box"]
    np.testing.assert_allclose(Z[:, win.W[f"o{jx}_pose"]], np.tile(box_at, (sd.grid.K, 1)), atol=1e-12)
    assert not Z[:, win.W[f"o{jx}_vel"]].any() and not Z[:, win.W[f"o{jx}_us"]].any()
    for name in ("x", "xd", "com", "u_left_foot", "u_right_hand", "slack"):
        np.testing.assert_array_equal(Z[:, win.W[name]], Zs[:, swin.W[name]])
    # multipliers of a standing object are zero, its pose included
    L = solver._onto_window(win, whole, swin, sd, Zs, primal=False)
    assert not L[:, win.W[f"o{jx}_pose"]].any()
