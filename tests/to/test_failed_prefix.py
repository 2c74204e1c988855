"""A segmented solve that fails hands back what it solved before the failure (solver._solved_prefix).

The solves are faked (each segment returns its own warm start, the second one as failed), so this
checks the stitching, the prefix problem and its evaluation, not ipopt."""
import numpy as np

from lomanip_to import solver
from lomanip_to.fixtures import load_problem


def test_a_failed_second_segment_returns_the_first_one_stitched_with_it(g1, monkeypatch):
    prob = load_problem("s1_basket", model=g1)
    segs = solver.segments(prob)
    assert len(segs) >= 2
    starts = []

    def fake_stages(run, data, win, wd, threads, label, **kwargs):
        lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, *solver.homotopy_stages(data.prob.options, data)[-1])
        z = np.asarray(W0, float).ravel(order="F")
        starts.append((data.grid.K, z.copy(), win))
        status = "Solve_Succeeded" if len(starts) == 1 else "Maximum_Iterations_Exceeded"
        return z, np.zeros_like(z), np.zeros(data.grid.K * win.G.n), status, None, {}, Pm, lbg, ubg, 0.0

    monkeypatch.setattr(solver, "_run_stages", fake_stages)
    res = solver.solve(prob, g1)
    assert len(starts) == 2   # stopped at the failed second segment
    assert not res.stats.converged and not res.success
    assert res.stats.status.startswith("Maximum_Iterations_Exceeded in subtask")
    (k0, z0, w0), (k1, _, w1) = starts
    assert res.t_knots[0] == 0.0 and abs(res.t_knots[-1] - segs[1][1]) < 1e-9
    assert len(res.t_knots) == k0 + k1 - 1   # the shared knot once
    # S1's segments carry their own objects (Options.segment_moving_objects): the box alone, not the basket
    assert w0.W.n < solver.get_window(g1, res.data.structure)[0].W.n
    first = z0.reshape(k0 + 1, w0.W.n)[:k0, w0.W["x"]]
    np.testing.assert_allclose(res.x_knots[:k0], first, atol=1e-12)   # the solved segment, unchanged
    box = z0.reshape(k0 + 1, w0.W.n)[:k0, w0.W["o0_pose"]]
    np.testing.assert_allclose(res.object_pose_knots["box"][:k0], box, atol=1e-12)


def test_stitched_object_angles_are_continuous_across_a_wrapped_join(g1):
    """A segment starts its objects from quaternions, so a yaw past pi comes back 2 pi lower (S2 5.0 kg
    at yaw -1.2: -3.143 then 3.140 at the join, a 6.28 violation of the box's kinematic row). The
    stitched trajectory unwraps the objects' angles; the robot's own columns are left as they are."""
    from lomanip_to.discretize import ProblemData

    prob = load_problem("case_lift_box", model=g1)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    K = data.grid.K
    j = data.midx["box"]
    cols = np.arange(win.W[f"o{j}_pose"].start, win.W[f"o{j}_pose"].stop)
    Z = np.zeros((K + 1, win.W.n))
    yaw = np.linspace(-2.9, -3.4, K)   # turning past -pi
    Z[:K, cols[5]] = np.where(yaw < -np.pi, yaw + 2 * np.pi, yaw)   # as a later segment hands it over
    Z[:K, win.W["x"].start + 5] = Z[:K, cols[5]]   # a robot column with the same jump stays untouched
    before = Z.copy()
    solver._unwrap_object_angles(win, data, Z)
    np.testing.assert_allclose(Z[:K, cols[5]], yaw, atol=1e-12)
    np.testing.assert_array_equal(Z[:, win.W["x"]], before[:, win.W["x"]])
    assert np.max(np.abs(np.diff(Z[:K, cols[5]]))) < 0.1
