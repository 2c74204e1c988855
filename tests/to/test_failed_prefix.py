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
        starts.append((data.grid.K, z.copy()))
        status = "Solve_Succeeded" if len(starts) == 1 else "Maximum_Iterations_Exceeded"
        return z, np.zeros_like(z), np.zeros(data.grid.K * win.G.n), status, None, {}, Pm, lbg, ubg, 0.0

    monkeypatch.setattr(solver, "_run_stages", fake_stages)
    res = solver.solve(prob, g1)
    assert len(starts) == 2   # stopped at the failed second segment
    assert not res.stats.converged and not res.success
    assert res.stats.status.startswith("Maximum_Iterations_Exceeded in subtask")
    (k0, z0), (k1, _) = starts
    assert res.t_knots[0] == 0.0 and abs(res.t_knots[-1] - segs[1][1]) < 1e-9
    assert len(res.t_knots) == k0 + k1 - 1   # the shared knot once
    win, _ = solver.get_window(g1, res.data.structure)
    first = z0.reshape(k0 + 1, win.W.n)[:k0, win.W["x"]]
    np.testing.assert_allclose(res.x_knots[:k0], first, atol=1e-12)   # the solved segment, unchanged
