"""The window-assembled Jacobian/gradient/Hessian equal CasADi's derivatives of the global NLP."""
import casadi as ca
import numpy as np

from lomanip_to import solver
from lomanip_to.assembly import AssembledNLP
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def test_assembled_derivatives_match_casadi(g1):
    prob = load_problem("case_lift_box", model=g1)
    data = ProblemData(prob, g1)
    win, wd = solver.get_window(g1, data.structure)
    K = 3
    nlp = AssembledNLP(wd, K, threads=1)
    rng = np.random.default_rng(1)
    z = rng.normal(scale=0.1, size=nlp.nz)
    p = rng.uniform(0.1, 1.0, size=nlp.npar)
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
