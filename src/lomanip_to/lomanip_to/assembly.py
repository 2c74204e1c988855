"""Sparse NLP assembly from ONE knot window: value, Jacobian, gradient and Lagrangian Hessian of the
window are built once in SX, mapped over all windows (2 threads), and their nonzeros scattered into
the global sparse Jacobian / (upper-triangular) Hessian by constant index maps.  ipopt receives
``grad_f``, ``jac_g`` and ``hess_lag`` directly, so CasADi never differentiates the global graph.

Measured (DESIGN.md sec. 5): this keeps construction at ~1-2 s for any horizon, where letting CasADi
build the derivatives of the expanded global NLP took 24 s at N=20 and 133 s at N=50.
"""

from __future__ import annotations

import time
from functools import cached_property

import casadi as ca
import numpy as np

from .transcription import Window


class WindowDerivatives:
    """SX Functions of one window: [g, f], Jacobian nonzeros, gradient, triu Hessian nonzeros."""

    def __init__(self, win: Window):
        t0 = time.perf_counter()
        a, b, p = win.a, win.b, win.p
        z = ca.vertcat(a, b)
        self.nw = win.W.n
        self.np = win.P.n
        self.ng = win.G.n
        self.F_gf = ca.Function("win_gf", [a, b, p], [win.g, win.f])
        J = ca.jacobian(win.g, z)
        self.J_sp = J.sparsity()
        self.F_j = ca.Function("win_j", [a, b, p], [ca.vertcat(*J.nonzeros())])
        gr = ca.gradient(win.f, z)
        self.F_grad = ca.Function("win_grad", [a, b, p], [gr])
        lam = ca.SX.sym("lam", self.ng)
        sig = ca.SX.sym("sig")
        H, _ = ca.hessian(sig * win.f + ca.dot(lam, win.g), z)
        H = ca.triu(H)
        self.H_sp = H.sparsity()
        self.F_h = ca.Function("win_h", [a, b, p, sig, lam], [ca.vertcat(*H.nonzeros())])
        self._win, self._sym = win, (a, b, p, sig, lam, z)
        self.build_time = time.perf_counter() - t0

    @cached_property
    def F_h_cost(self) -> ca.Function:
        """The cost's Hessian alone, on the Lagrangian's sparsity (the constraints' curvature
        dropped, as in Gauss-Newton SQP and Crocoddyl's DDP); built only when a solve asks for it."""
        a, b, p, sig, lam, z = self._sym
        Hc = ca.project(ca.triu(ca.hessian(sig * self._win.f, z)[0]), self.H_sp)
        return ca.Function("win_h_cost", [a, b, p, sig, lam], [ca.vertcat(*Hc.nonzeros())])


def _ccs_from_triplets(nrow, ncol, rows, cols):
    """Unique (row, col) pairs -> (Sparsity, position of each input triplet in the CCS nonzeros)."""
    lin = cols.astype(np.int64) * nrow + rows.astype(np.int64)
    uniq, inv = np.unique(lin, return_inverse=True)
    ur = (uniq % nrow).astype(np.int64)
    uc = (uniq // nrow).astype(np.int64)
    colind = np.zeros(ncol + 1, dtype=np.int64)
    np.add.at(colind, uc + 1, 1)
    colind = np.cumsum(colind)
    sp = ca.Sparsity(int(nrow), int(ncol), colind.tolist(), ur.tolist())
    return sp, inv, len(uniq)


class AssembledNLP:
    """Global NLP over z = vec(W) (n_w x (K+1) knots incl. a fixed dummy knot), p = vec(P)."""

    def __init__(self, wd: WindowDerivatives, K: int, threads: int = 2):
        t0 = time.perf_counter()
        self.K = K
        nw, npar, ng = wd.nw, wd.np, wd.ng
        self.nz = nw * (K + 1)
        self.npar = npar * K
        self.ngg = ng * K
        z = ca.MX.sym("z", self.nz)
        p = ca.MX.sym("p", self.npar)
        Wm = ca.reshape(z, nw, K + 1)
        A = Wm[:, 0:K]
        B = Wm[:, 1:K + 1]
        Pm = ca.reshape(p, npar, K)
        mode = "thread" if threads > 1 else "serial"
        gf_map = wd.F_gf.map(K, mode, threads) if mode == "thread" else wd.F_gf.map(K)
        j_map = wd.F_j.map(K, mode, threads) if mode == "thread" else wd.F_j.map(K)
        gr_map = wd.F_grad.map(K, mode, threads) if mode == "thread" else wd.F_grad.map(K)
        Gm, Fm = gf_map(A, B, Pm)
        g = ca.vec(Gm)
        f = ca.sum2(Fm)
        self.F_nlp = ca.Function("nlp", [z, p], [f, g])

        # Jacobian: rows of window k are k*ng + r, columns k*nw + c (c < 2 nw)
        jr, jc = wd.J_sp.get_triplet()
        jr, jc = np.asarray(jr), np.asarray(jc)
        nnzj = len(jr)
        rows = (np.arange(K)[:, None] * ng + jr[None, :]).ravel()
        cols = (np.arange(K)[:, None] * nw + jc[None, :]).ravel()
        sp_j, inv_j, nu = _ccs_from_triplets(self.ngg, self.nz, rows, cols)
        assert nu == len(rows), "window Jacobian rows must not overlap"
        perm = np.empty(len(rows), dtype=np.int64)
        perm[inv_j] = np.arange(len(rows))
        Jm = j_map(A, B, Pm)  # nnzj x K ; vec is column-major = window-major
        jac_nz = ca.vec(Jm)[perm.tolist()]
        self.F_jac = ca.Function("jac_g", [z, p], [g, ca.sparsity_cast(jac_nz, sp_j)])
        self.jac_sp = sp_j
        self.nnz_jac = nnzj * K

        # gradient: sum overlaps
        gcols = (np.arange(K)[:, None] * nw + np.arange(2 * nw)[None, :]).ravel()
        S = ca.DM(ca.Sparsity.triplet(self.nz, len(gcols), gcols.tolist(), list(range(len(gcols)))),
                  np.ones(len(gcols)))
        grad = ca.mtimes(S, ca.vec(gr_map(A, B, Pm)))
        self.F_grad = ca.Function("grad_f", [z, p], [f, grad])

        # Hessian (upper triangle), overlaps summed
        hr, hc = wd.H_sp.get_triplet()
        hr, hc = np.asarray(hr), np.asarray(hc)
        rows = (np.arange(K)[:, None] * nw + hr[None, :]).ravel()
        cols = (np.arange(K)[:, None] * nw + hc[None, :]).ravel()
        sp_h, inv_h, nu = _ccs_from_triplets(self.nz, self.nz, rows, cols)
        Sh = ca.DM(ca.Sparsity.triplet(nu, len(rows), inv_h.tolist(), list(range(len(rows)))),
                   np.ones(len(rows)))
        self._wd, self._hess_args = wd, (z, p, A, B, Pm, Sh, sp_h, mode, threads)
        self._hessians: dict = {}
        self.F_hess = self.hessian("exact")
        self.nnz_hess = nu
        self.z_sym, self.p_sym = z, p
        self.f_expr, self.g_expr = f, g
        self.build_time = time.perf_counter() - t0

    def hessian(self, kind: str = "exact") -> ca.Function:
        """``hess_lag(z, p, lam_f, lam_g)`` of the whole NLP: "exact" (Lagrangian) or "cost"."""
        if kind not in self._hessians:
            z, p, A, B, Pm, Sh, sp_h, mode, threads = self._hess_args
            F = {"exact": self._wd.F_h, "cost": self._wd.F_h_cost}[kind]
            K, ng = self.K, self._wd.ng
            lam_f = ca.MX.sym("lam_f")
            lam_g = ca.MX.sym("lam_g", self.ngg)
            hm = F.map(K, mode, threads) if mode == "thread" else F.map(K)
            Hm = hm(A, B, Pm, ca.repmat(lam_f, 1, K), ca.reshape(lam_g, ng, K))
            h_nz = ca.mtimes(Sh, ca.vec(Hm))
            self._hessians[kind] = ca.Function("hess_lag", [z, p, lam_f, lam_g], [ca.sparsity_cast(h_nz, sp_h)])
        return self._hessians[kind]

    def solver(self, ipopt_opts: dict, iteration_callback=None, hessian: str = "exact",
               rows: np.ndarray | None = None) -> ca.Function:
        """ipopt on the assembled NLP; ``hessian`` "exact" (Lagrangian) or "cost" (constraint
        curvature dropped).  ``rows`` (sorted indices into g) keeps only those constraint rows.

        Why ``rows``: one window Function serves every knot, so a row that does not apply at a knot
        is switched off with infinite bounds.  ipopt keeps such a row (and a free slack for it) in
        every KKT factorisation; on S1/S2 more than half of the rows are free (e.g. 4625 of 10527 in
        S1's last subtask).  Handing ipopt only the bounded rows shrinks the factorised system."""
        if rows is None:
            g, jac, hess = self.g_expr, self.F_jac, self.hessian(hessian)
        else:
            sel = [int(r) for r in rows]
            z, p = self.z_sym, self.p_sym
            g = self.g_expr[sel]
            g_full, J_full = self.F_jac(z, p)
            jac = ca.Function("jac_g", [z, p], [g_full[sel], J_full[sel, :]])
            lam_f = ca.MX.sym("lam_f")
            lam = ca.MX.sym("lam_g", len(sel))
            scatter = ca.DM(ca.Sparsity.triplet(self.ngg, len(sel), sel, list(range(len(sel)))), 1.0)
            H = self.hessian(hessian)(z, p, lam_f, ca.mtimes(scatter, lam))
            hess = ca.Function("hess_lag", [z, p, lam_f, lam], [H])
        nlp = {"x": self.z_sym, "p": self.p_sym, "f": self.f_expr, "g": g}
        opts = {"grad_f": self.F_grad, "jac_g": jac, "hess_lag": hess,
                "print_time": False, "ipopt": ipopt_opts}
        if iteration_callback is not None:
            opts["iteration_callback"] = iteration_callback
        return ca.nlpsol("to", "ipopt", nlp, opts)
