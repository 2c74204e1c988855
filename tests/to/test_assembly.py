"""The window-assembled Jacobian/gradient/Hessian equal CasADi's derivatives of the global NLP."""
import casadi as ca
import numpy as np

from lomanip_to import solver
from lomanip_to.assembly import AssembledNLP, WindowDerivatives
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def _lift_box(g1):
    """(problem, ProblemData, Window, WindowDerivatives) of case_lift_box, the small case with box pairs."""
    prob = load_problem("case_lift_box", model=g1)
    data = ProblemData(prob, g1)
    return (prob, data) + tuple(solver.get_window(g1, data.structure))


def _random_nlp_point(wd, K: int, seed: int):
    """A K-knot NLP on one thread, a random point and random parameters."""
    nlp = AssembledNLP(wd, K, threads=1)
    rng = np.random.default_rng(seed)
    return nlp, rng, rng.normal(scale=0.1, size=nlp.nz), rng.uniform(0.1, 1.0, size=nlp.npar)


def test_assembled_derivatives_match_casadi(g1):
    _, _, win, wd = _lift_box(g1)
    nlp, rng, z, p = _random_nlp_point(wd, 3, seed=1)
    lam_g = rng.normal(size=nlp.ngg)
    # reference: differentiate the global (mapped) expressions directly
    f, g = nlp.f_expr, nlp.g_expr
    Jref = ca.Function("J", [nlp.z_sym, nlp.p_sym], [ca.jacobian(g, nlp.z_sym)])(z, p)
    _, J = nlp.F_jac(z, p)
    assert np.allclose(np.array(ca.densify(J)), np.array(ca.densify(Jref)), atol=1e-9)
    gref = ca.Function("gr", [nlp.z_sym, nlp.p_sym], [ca.gradient(f, nlp.z_sym)])(z, p)
    _, gr = nlp.F_grad(z, p)
    assert np.allclose(np.array(gr).ravel(), np.array(gref).ravel(), atol=1e-9)
    lf = ca.MX.sym("lf")
    lg = ca.MX.sym("lg", nlp.ngg)
    H = ca.hessian(lf * f + ca.dot(lg, g), nlp.z_sym)[0]
    Href = ca.Function("H", [nlp.z_sym, nlp.p_sym, lf, lg], [ca.triu(H)])(z, p, 0.7, lam_g)
    Hs = nlp.F_hess(z, p, 0.7, lam_g)
    assert np.allclose(np.array(ca.densify(Hs)), np.array(ca.densify(Href)), atol=1e-7)
    # the "cost" Hessian (Options.guide_hessian / final_hessian) is the exact one without the
    # constraints' curvature: whatever the multipliers, it equals the exact one at lam_g = 0
    Hc = nlp.hessian("cost")(z, p, 0.7, lam_g)
    H0 = nlp.F_hess(z, p, 0.7, np.zeros(nlp.ngg))
    assert np.allclose(np.array(ca.densify(Hc)), np.array(ca.densify(H0)), atol=1e-9)
    assert not np.allclose(np.array(ca.densify(Hc)), np.array(ca.densify(Hs)), atol=1e-6)


def test_split_hessian_skips_only_zero_collision_curvature(g1):
    """The Hessian that evaluates each collision pair only where its multipliers or penalty are
    nonzero equals the whole window's Hessian, with pairs skipped and pairs evaluated."""
    prob, data, win, wd = _lift_box(g1)
    assert wd.split and win.collision_groups
    stages = solver.homotopy_stages(prob.options, data)
    rng = np.random.default_rng(2)
    skipped = evaluated = 0
    for stage in (stages[0], stages[-1]):   # the surrogate penalties on, then the hard rows alone
        _, _, _, _, Pm, W0 = data.fill(win, *stage)
        for k in range(data.grid.K):
            lam = rng.normal(size=win.G.n)
            for i, grp in enumerate(win.collision_groups):
                if (i + k) % 3:   # most pairs as the collision screen leaves them: multipliers 0
                    lam[grp.rows] = 0.0
            a, b, p = W0[:, k] + rng.normal(scale=0.02, size=win.W.n), W0[:, k + 1], Pm[:, k]
            flags = np.array(wd.F_active(a, b, p, 0.7, lam)).ravel()
            skipped += int(np.sum(flags == 0))
            evaluated += int(np.sum(flags == 1))
            h_split = np.array(wd.F_h(a, b, p, 0.7, lam)).ravel()
            h_full = np.array(wd.F_h_full(a, b, p, 0.7, lam)).ravel()
            assert np.allclose(h_split, h_full, rtol=1e-10, atol=1e-9 * (1 + np.abs(h_full).max()))
    assert skipped > 0 and evaluated > 0


def test_split_hessian_can_be_switched_off(g1):
    _, _, win, _ = _lift_box(g1)
    wd = WindowDerivatives(win, split=False)
    assert not wd.split and wd.F_h is wd.F_h_full


def test_jacobian_of_the_nlp_rows_skips_only_left_out_pairs(g1):
    """With a row selection (the collision screen's), the Jacobian evaluates a pair only at knots
    where the selection holds its rows; the selected rows equal the whole Jacobian's."""
    _, _, win, wd = _lift_box(g1)
    K = 4
    nlp, _, z, p = _random_nlp_point(wd, K, seed=3)
    keep = np.ones(nlp.ngg, bool)
    for i, grp in enumerate(win.collision_groups):
        for k in range(K):
            if (i + k) % 3:
                keep[k * wd.ng + grp.rows] = False
    rows = np.flatnonzero(keep)
    on = wd.groups_on(rows, K)
    assert 0 < on.sum() < on.size
    _, J_sel = nlp.jacobian(rows)(z, p)
    _, J_all = nlp.F_jac(z, p)
    J_sel, J_all = np.array(ca.densify(J_sel)), np.array(ca.densify(J_all))
    assert np.allclose(J_sel[rows], J_all[rows], rtol=1e-12, atol=1e-12)
    assert not np.allclose(J_sel, J_all)   # the left-out pairs were not evaluated
