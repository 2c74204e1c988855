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


#: evaluate each collision pair's curvature only at the knots where it is not zero
#: (WindowDerivatives); False gives the whole window's Lagrangian Hessian in one piece at every knot
SPLIT_COLLISION_DERIVATIVES = True


class WindowDerivatives:
    """SX Functions of one window: [g, f], Jacobian nonzeros, gradient, triu Hessian nonzeros.

    Why the Hessian is split (``split``, default :data:`SPLIT_COLLISION_DERIVATIVES`): the
    collision pairs' rows and penalties are about half of the window's Lagrangian Hessian (S1's
    carry: 0.63 M of 1.17 M instructions; the demo push: 0.46 M of 0.77 M), yet a pair whose rows
    are not in ipopt's NLP (the collision screen leaves the far ones out, so their multipliers are
    0) and whose penalty is flat (no penetration, outside its surrogate) adds exactly zero.  ``F_h``
    is therefore the rest's Hessian plus, per pair, a conditional (``Function.conditional``) that
    evaluates the pair's part only where its multipliers or penalty activity are nonzero: exact,
    only zero terms are skipped.  Where every pair is in the NLP (no screen) the pairs' shared
    kinematics make the one-piece ``F_h_full`` cheaper (assembly measured: 110 ms vs 230 ms for
    the push's 45 knots with every pair active, 58 ms with none)."""

    def __init__(self, win: Window, split: bool | None = None):
        t0 = time.perf_counter()
        a, b, p = win.a, win.b, win.p
        z = ca.vertcat(a, b)
        self.nw = win.W.n
        self.np = win.P.n
        self.ng = win.G.n
        self.F_gf = ca.Function("win_gf", [a, b, p], [win.g, win.f])
        self.F_f = ca.Function("win_f", [a, b, p], [win.f])   # the cost alone, for grad_f's value
        J = ca.jacobian(win.g, z)
        self.J_sp = J.sparsity()
        self.F_j = ca.Function("win_j", [a, b, p], [ca.vertcat(*J.nonzeros())])
        lam = ca.SX.sym("lam", self.ng)
        sig = ca.SX.sym("sig")
        self._win, self._sym = win, (a, b, p, sig, lam, z)
        self.F_grad = ca.Function("win_grad", [a, b, p], [ca.gradient(win.f, z)])
        H = ca.triu(ca.hessian(sig * win.f + ca.dot(lam, win.g), z)[0])
        self.H_sp = H.sparsity()
        self.F_h_full = ca.Function("win_h", [a, b, p, sig, lam], [ca.vertcat(*H.nonzeros())])
        self._groups = list(getattr(win, "collision_groups", []))
        self.split = bool(SPLIT_COLLISION_DERIVATIVES if split is None else split) and bool(self._groups)
        self.build_time = time.perf_counter() - t0

    @property
    def F_h(self) -> ca.Function:
        """The window's Lagrangian Hessian: split by collision pair (built at first use) or one piece."""
        return self._split["F_h"] if self.split else self.F_h_full

    @property
    def F_active(self) -> ca.Function:
        """(a, b, p, sig, lam) -> 1 per collision pair whose curvature is evaluated."""
        return self._split["F_active"]

    @property
    def F_j_on(self) -> ca.Function:
        """(a, b, p, on) -> Jacobian nonzeros, each collision pair's only where ``on`` is 1."""
        return self._split["F_j_on"]

    @property
    def group_rows(self) -> list:
        return [grp.rows for grp in self._groups]

    @cached_property
    def _split(self) -> dict:
        t0 = time.perf_counter()
        out = self._build_split(self._win, self._groups)
        self.build_time += time.perf_counter() - t0
        return out

    def _build_split(self, win: Window, groups: list) -> dict:
        a, b, p, sig, lam, z = self._sym
        col = np.concatenate([grp.rows for grp in groups])
        main = np.setdiff1d(np.arange(self.ng), col).tolist()
        H_main = ca.triu(ca.hessian(sig * win.f_main + ca.dot(lam[main], win.g[main]), z)[0])
        rows = [grp.rows.tolist() for grp in groups]
        H_grp = [ca.triu(ca.hessian(sig * grp.penalty + ca.dot(lam[r], win.g[r]), z)[0]) for grp, r in zip(groups, rows)]
        # each part on its entries of the whole Hessian's sparsity: the Hessian is linear in the
        # Lagrangian's terms, so where the whole one is structurally zero the parts sum to zero
        sp = self.H_sp
        H_grp = [ca.project(H, H.sparsity() * sp) for H in H_grp]
        args = [a, b, p, sig, lam]
        h_main = ca.Function("win_h_main", args, [ca.vertcat(*ca.project(H_main, sp).nonzeros())])
        # per pair: may its curvature be nonzero (a multiplier, or its penalty's indicator)?
        act_h = ca.vertcat(*[grp.active + ca.sum1(ca.fabs(lam[r])) for grp, r in zip(groups, rows)]) > 0
        F_act = ca.Function("win_collision_active", args, [act_h])
        A, B, P = ca.MX.sym("a", self.nw), ca.MX.sym("b", self.nw), ca.MX.sym("p", self.np)
        S, L = ca.MX.sym("sig"), ca.MX.sym("lam", self.ng)
        flags = F_act(A, B, P, S, L)
        h_parts, h_pos = [], []
        for i, H in enumerate(H_grp):
            if H.nnz():
                h_pos.append(_positions(sp, H.sparsity()))
                F = ca.Function.conditional(f"win_h_{i}", ca.Function(f"h_{i}", args, [ca.vertcat(*H.nonzeros())]))
                h_parts.append(F(flags[i], A, B, P, S, L))
        h = h_main(A, B, P, S, L) + _scatter_sum(h_parts, h_pos, sp.nnz())
        # the Jacobian: the rest's rows, plus each pair's rows where ``on`` (the NLP's rows) has them
        on = ca.MX.sym("on", len(groups))
        Jm = ca.jacobian(win.g[main], z)
        j_parts, j_pos = [], []
        for i, (grp, r) in enumerate(zip(groups, rows)):
            Jg = ca.jacobian(win.g[r], z)
            if Jg.nnz():
                j_pos.append(_positions(self.J_sp, Jg.sparsity(), grp.rows))
                F = ca.Function.conditional(f"win_j_{i}", ca.Function(f"j_{i}", [a, b, p], [ca.vertcat(*Jg.nonzeros())]))
                j_parts.append(F(on[i], A, B, P))
        j_main = ca.Function("win_j_main", [a, b, p], [ca.vertcat(*Jm.nonzeros())])
        jac = _scatter_sum([j_main(A, B, P)] + j_parts, [_positions(self.J_sp, Jm.sparsity(), main)] + j_pos,
                           self.J_sp.nnz())
        return {"F_h": ca.Function("win_h_split", [A, B, P, S, L], [h]), "F_active": F_act,
                "F_j_on": ca.Function("win_j_on", [A, B, P, on], [jac])}

    def groups_on(self, rows: np.ndarray, K: int) -> np.ndarray:
        """n_groups x K: 1 where the NLP's ``rows`` (global indices) hold one of the pair's rows."""
        sel = np.zeros(K * self.ng, bool)
        sel[np.asarray(rows, np.int64)] = True
        sel = sel.reshape(K, self.ng)
        return np.array([sel[:, r].any(axis=1) for r in self.group_rows], float).reshape(len(self.group_rows), K)

    @cached_property
    def F_h_cost(self) -> ca.Function:
        """The cost's Hessian alone, on the Lagrangian's sparsity (the constraints' curvature
        dropped, as in Gauss-Newton SQP and Crocoddyl's DDP); built only when a solve asks for it."""
        a, b, p, sig, lam, z = self._sym
        Hc = ca.project(ca.triu(ca.hessian(sig * self._win.f, z)[0]), self.H_sp)
        return ca.Function("win_h_cost", [a, b, p, sig, lam], [ca.vertcat(*Hc.nonzeros())])


def _positions(sp: ca.Sparsity, sub: ca.Sparsity, row_of=None) -> np.ndarray:
    """Index of each nonzero of ``sub`` among the nonzeros of ``sp`` (``sub`` inside ``sp``; with
    ``row_of``, row i of ``sub`` is row ``row_of[i]`` of ``sp``)."""
    r, c = (np.asarray(v, np.int64) for v in sp.get_triplet())
    rs, cs = (np.asarray(v, np.int64) for v in sub.get_triplet())
    if row_of is not None:
        rs = np.asarray(row_of, np.int64)[rs]
    lin = c * sp.size1() + r   # column-major order: ascending
    want = cs * sp.size1() + rs
    pos = np.minimum(np.searchsorted(lin, want), len(lin) - 1)
    assert np.array_equal(lin[pos], want), "sparsity is not a subset"
    return pos


def _scatter_sum(parts: list, positions: list, n: int) -> ca.MX:
    """sum_i e[positions_i] += parts_i, as one constant sparse product."""
    if not parts:
        return ca.MX.zeros(n, 1)
    pos = np.concatenate(positions)
    S = ca.DM(ca.Sparsity.triplet(n, len(pos), pos.tolist(), list(range(len(pos)))), 1.0)
    return ca.mtimes(S, ca.vertcat(*parts))


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
        self._jac_args = (z, p, A, B, Pm, g, perm, sp_j, mode, threads)
        self.jac_sp = sp_j
        self.nnz_jac = nnzj * K

        # gradient: sum overlaps
        gcols = (np.arange(K)[:, None] * nw + np.arange(2 * nw)[None, :]).ravel()
        S = ca.DM(ca.Sparsity.triplet(self.nz, len(gcols), gcols.tolist(), list(range(len(gcols)))),
                  np.ones(len(gcols)))
        grad = ca.mtimes(S, ca.vec(gr_map(A, B, Pm)))
        f_map = wd.F_f.map(K, mode, threads) if mode == "thread" else wd.F_f.map(K)
        self.F_grad = ca.Function("grad_f", [z, p], [ca.sum2(f_map(A, B, Pm)), grad])

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
        self.nnz_hess = nu
        self.z_sym, self.p_sym = z, p
        self.f_expr, self.g_expr = f, g
        self.build_time = time.perf_counter() - t0

    @property
    def F_hess(self) -> ca.Function:
        return self.hessian("exact")

    def hessian(self, kind: str = "exact") -> ca.Function:
        """``hess_lag(z, p, lam_f, lam_g)`` of the whole NLP: "exact" (Lagrangian; each collision
        pair's curvature only where it is not zero), "exact_full" (the same values, the window's
        Hessian in one piece at every knot) or "cost"."""
        if kind not in self._hessians:
            z, p, A, B, Pm, Sh, sp_h, mode, threads = self._hess_args
            F = getattr(self._wd, {"exact": "F_h", "exact_full": "F_h_full", "cost": "F_h_cost"}[kind])
            K, ng = self.K, self._wd.ng
            lam_f = ca.MX.sym("lam_f")
            lam_g = ca.MX.sym("lam_g", self.ngg)
            hm = F.map(K, mode, threads) if mode == "thread" else F.map(K)
            Hm = hm(A, B, Pm, ca.repmat(lam_f, 1, K), ca.reshape(lam_g, ng, K))
            h_nz = ca.mtimes(Sh, ca.vec(Hm))
            self._hessians[kind] = ca.Function("hess_lag", [z, p, lam_f, lam_g], [ca.sparsity_cast(h_nz, sp_h)])
        return self._hessians[kind]

    def jacobian(self, rows: np.ndarray | None = None) -> ca.Function:
        """``jac_g(z, p) -> (g, J)``; with ``rows`` (and the split window), a collision pair's
        Jacobian is evaluated only at the knots where ``rows`` hold one of its rows (elsewhere its
        entries are 0: rows left out of the NLP)."""
        if rows is None or not self._wd.split:
            return self.F_jac
        z, p, A, B, Pm, g, perm, sp_j, mode, threads = self._jac_args
        wd, K = self._wd, self.K
        j_map = wd.F_j_on.map(K, mode, threads) if mode == "thread" else wd.F_j_on.map(K)
        jac_nz = ca.vec(j_map(A, B, Pm, ca.DM(wd.groups_on(rows, K))))[perm.tolist()]
        return ca.Function("jac_g", [z, p], [g, ca.sparsity_cast(jac_nz, sp_j)])

    def solver(self, ipopt_opts: dict, iteration_callback=None, hessian: str = "exact",
               rows: np.ndarray | None = None) -> ca.Function:
        """ipopt on the assembled NLP; ``hessian`` a kind of :meth:`hessian` ("exact", "exact_full",
        "cost": constraint curvature dropped).  ``rows`` (sorted indices into g) keeps only those constraint rows.

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
            g_full, J_full = self.jacobian(rows)(z, p)
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
