"""Solve a :class:`~lomanip_to.problem.Problem`: validate, discretise, assemble, ipopt, report.

Design (decided by the measurements in DESIGN.md sec. 5 and in ``scripts/bench_to.py``):
one symbolic knot window (``transcription.Window``) whose value/Jacobian/gradient/Lagrangian-Hessian
are built once in SX and mapped over the horizon (``assembly``); ipopt (MUMPS) gets the assembled
sparse derivatives.  Window Functions and assembled NLPs are cached in memory per structure (number
of moving objects, collision pairs) and horizon length, so re-solves (homotopy stages, ablations,
grid cells with the same structure) skip construction.  Collision homotopy: stage 1 solves with the
ellipsoid surrogate (exponent 2) and no hard collision rows, stage 2 warm-starts from it with the
sharper surrogate and the hard penetration constraint.
"""

from __future__ import annotations

import hashlib
import re
import resource
import time

import casadi as ca
import numpy as np

from . import screening
from .assembly import AssembledNLP, WindowDerivatives
from .checks import penetration_per_knot, run_checks
from .discretize import ProblemData, _lifts, reaches
from .model import FEET, HANDS, LIMBS, G1Model, rpy_to_rot
from .problem import TO_NOT_CONVERGED, WALKING, Problem, validate_problem
from .result import (CAPPED_FEASIBLE_STATUS, FEASIBLE_BEFORE_STOP_STATUS, STALLED_STATUS, STOPPED_EARLY_STATUSES,
                     Progress, SolverStats, TOResult, Violation)
from .transcription import Window

_WINDOWS: dict = {}
_NLPS: dict = {}
_SOLVERS: dict = {}
_MODEL: list = []
_CALLBACKS: dict = {}
_TRANSIENT: set = set()   # keys of the screened solvers in _SOLVERS
#: solvers kept per process (one per structure, options and active-row set); the oldest is dropped
#: beyond this, so a long-running TO node does not grow without bound
MAX_CACHED_SOLVERS = 48
#: iteration cap of the homotopy guide stage (ellipsoid surrogate); the final stage is not capped.
#: The guide should normally converge (to ipopt's acceptable level): only then does the final stage
#: get a primal-dual warm start, which then takes a few iterations (S1 subtask 0: guide 127 + final
#: 16).  With a cap of 80 the guide stopped early and the final stage failed from a cold barrier.
GUIDE_STAGE_MAX_ITER = 300
#: tolerances of the guide stage: it only has to bring the final stage near its solution, not
#: resolve the surrogate's optimum to 1e-4 (push_trolley: guide 284 iterations at the default
#: tolerances, the last ~180 of them reducing the objective from 279 to 138 at constant violation)
GUIDE_STAGE_TOLERANCES = {"tol": 1e-2, "acceptable_tol": 1e-1, "acceptable_constr_viol_tol": 1e-2,
                          "acceptable_iter": 3}
#: the stall acceptance counts an iterate within this many times constr_tol whose objective lies
#: well below the best feasible one as progress.  Why: a demo push stalled on its best feasible
#: iterate (objective 884) while ipopt's iterates, at violations of 1e-3, had come down to 58 and
#: went on falling; the plan handed back failed the momentum check between knots (session 25)
STALL_NEAR_FEASIBLE = 100.0
#: horizons up to this many knots are solved in one piece (segmenting only pays for long tasks)
SEGMENT_MIN_KNOTS = 60

DYNAMICS_ROWS = ("kinematic integration", "CoM integration", "linear momentum dynamics",
                 "angular momentum dynamics", "CoM consistency", "centroidal momentum consistency (CMM)",
                 "linear dynamics", "angular dynamics", "attachment", "nonholonomic")


def default_model() -> G1Model:
    if not _MODEL:
        _MODEL.append(G1Model())
    return _MODEL[0]


def get_window(model: G1Model, structure):
    key = structure
    if key not in _WINDOWS:
        win = Window(model, structure)
        _WINDOWS[key] = (win, WindowDerivatives(win))
    return _WINDOWS[key]


class _IterationCallback(ca.Callback):
    """ipopt iteration hook: forwards (objective, constraint values) of every iteration to the active
    progress sink.  One instance per cached solver; the sink is swapped per solve."""

    def __init__(self, name: str, nx: int, ng: int, np_: int):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.np_ = nx, ng, np_
        self.sink = None
        self.construct(name, {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        n = ca.nlpsol_out(i)
        if n == "f":
            return ca.Sparsity.scalar()
        if n in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if n in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        if n == "lam_p":
            return ca.Sparsity.dense(self.np_)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        if self.sink is not None:
            names = ca.nlpsol_out()
            g = np.asarray(arg[names.index("g")]).ravel()
            f = float(arg[names.index("f")])
            point = lambda: tuple(np.array(arg[names.index(n)]).ravel() for n in ("x", "lam_x", "lam_g"))
            return [1 if self.sink(f, g, point) else 0]
        return [0]


def _make_solver(nlp: AssembledNLP, opts: dict, hessian: str = "exact", rows: np.ndarray | None = None):
    ng = nlp.ngg if rows is None else len(rows)
    cb = _IterationCallback(f"progress_{len(_SOLVERS)}", nlp.nz, ng, nlp.npar)
    s = nlp.solver(opts, iteration_callback=cb, hessian=hessian, rows=rows)
    _CALLBACKS[id(s)] = cb  # keep the callback alive with its solver
    return s


def active_rows(lbg: np.ndarray, ubg: np.ndarray) -> np.ndarray:
    """Indices of the constraint rows with a finite bound (the others are switched off)."""
    return np.flatnonzero(np.isfinite(lbg) | np.isfinite(ubg))


def get_solver(wd, structure, K: int, ipopt_opts: dict, threads: int = 2, tag: str = "main",
               hessian: str = "exact", rows: np.ndarray | None = None, transient: bool = False):
    """Cached ipopt solver per (structure, K, options, active rows).  ``transient``: a row set that
    will not recur (screened at one point, ``Options.collision_screen_distance``): it replaces the
    previous transient solver instead of filling the cache."""
    nlp = get_nlp(wd, structure, K, threads)
    rkey = None if rows is None else hashlib.sha1(np.asarray(rows, np.int64).tobytes()).hexdigest()
    skey = (tag, hessian, (structure, K), tuple(sorted(ipopt_opts.items())), rkey)
    if skey not in _SOLVERS:
        stale = [k for k in _SOLVERS if k in _TRANSIENT] if transient else []
        while stale or len(_SOLVERS) >= MAX_CACHED_SOLVERS:
            key = stale.pop() if stale else next(iter(_SOLVERS))
            _TRANSIENT.discard(key)
            _CALLBACKS.pop(id(_SOLVERS.pop(key)), None)
        _SOLVERS[skey] = _make_solver(nlp, ipopt_opts, hessian, rows)
        if transient:
            _TRANSIENT.add(skey)
    return nlp, _SOLVERS[skey]


def homotopy_stages(opt, data: ProblemData | None = None) -> list:
    """[(exponent, hard, penalty, homotopy)] solved in sequence, each warm-started.  ``homotopy`` is
    True (surrogate rows with slacks), "penalty" (the surrogate as a penalty, no slacks) or False;
    ``Options.homotopy_form`` "auto" picks the penalty for an NLP (``data``) that carries an object
    while walking (:func:`carries_object`)."""
    if not opt.collision_homotopy:
        return [(2.0, opt.collision_hard_constraint, opt.collision_penalty, False)]
    hard = opt.collision_hard_constraint
    form = opt.homotopy_form
    if form == "auto":
        form = "penalty" if data is not None and carries_object(data) else "slacks"
    if form == "slacks":
        return [(2.0, False, opt.collision_penalty, True), (6.0, hard, opt.collision_penalty, True)]
    return [(2.0, False, opt.collision_penalty, "penalty"), (6.0, hard, opt.collision_penalty, False if hard else "penalty")]


def carries_object(data: ProblemData) -> bool:
    """Whether some moving object is carried (free: off its support, held by the hands) while the
    robot walks: S1's carry.  A lift in place (``case_lift_box``) converges faster with the slacks
    (80 iterations against 140)."""
    return any(data.obj_mode(k, oid) == "free" and data.prob.phases[data.grid.phase[k]].phase_type == WALKING
               for oid in data.midx for k in range(data.grid.K))


def _ipopt_options(opt) -> dict:
    o = {
        "max_iter": int(opt.max_iterations), "tol": float(opt.tol), "constr_viol_tol": float(opt.constr_tol),
        "acceptable_tol": 1e-2, "acceptable_constr_viol_tol": 1e-3, "acceptable_iter": 10,
        "print_level": int(opt.print_level), "linear_solver": "mumps", "mu_strategy": "adaptive",
        "bound_push": 1e-6, "bound_frac": 1e-6, "nlp_scaling_max_gradient": 100.0, "sb": "yes",
    }
    o.update(opt.ipopt or {})
    return o


def _warm_options(o: dict) -> dict:
    w = dict(o)
    w.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-6,
              "warm_start_mult_bound_push": 1e-6, "mu_init": 1e-4})
    return w


class _Run:
    """State of one solve: start time, iteration count, stage log, progress reporting."""

    def __init__(self, prob: Problem, progress, t_start: float):
        self.prob, self.progress, self.t_start = prob, progress, t_start
        self.iterations = 0
        self.stages: list = []
        self.timed_out = False
        self.stalled = False
        self.guide_point = None   # the primal point a final stage started from

    def sink(self, stage: str, lbg: np.ndarray, ubg: np.ndarray, stall: bool = False):
        """Per-iteration hook ``fn(f, g, point=None)``; ``point()`` gives (x, lam_x, lam_g) of the
        iterate.  With ``stall`` it also applies the stall acceptance of Options and keeps the best
        feasible iterate in ``self.best`` (f, x, lam_x, lam_g)."""
        opt = self.prob.options
        window = int(opt.stall_iterations) if stall else 0
        best_f: list = []  # best feasible objective after each iteration (inf before the first)
        near_f: list = []  # objective of each iterate within STALL_NEAR_FEASIBLE x constr_tol (else inf)
        self.stalled = False
        self.best = None

        def fn(f, g, point=None):
            self.iterations += 1
            viol = float(np.max(np.maximum(np.maximum(lbg - g, g - ubg), 0.0), initial=0.0))
            elapsed = time.perf_counter() - self.t_start
            if self.progress is not None:
                try:
                    self.progress(Progress(self.iterations, f, viol, stage, elapsed))
                except Exception:  # noqa: BLE001 - a broken logger must not kill the solve
                    pass
            if window > 0:
                if viol <= opt.constr_tol and (self.best is None or f < self.best[0]):
                    self.best = (float(f),) + (point() if point is not None else (None, None, None))
                best_f.append(self.best[0] if self.best is not None else np.inf)
                near_f.append(float(f) if viol <= STALL_NEAR_FEASIBLE * opt.constr_tol else np.inf)
                if len(best_f) > window and np.isfinite(best_f[-window - 1]):
                    # progress = a better feasible iterate, or a nearly feasible one well below it
                    lowest = min(best_f[-1], min(near_f[-window:]))
                    if best_f[-window - 1] - lowest <= opt.stall_rtol * max(1.0, abs(best_f[-1])):
                        self.stalled = True
                        return True
            if elapsed > self.prob.options.time_limit:
                self.timed_out = True
                return True
            return False
        return fn


def _run_stages(run: _Run, data: ProblemData, win, wd, threads, label: str, z0=None, lam=None, stages=None,
                max_iter: int | None = None):
    """Homotopy stages on one ProblemData; returns (z, lam_x, lam_g, status, nlp, args, Pm, lbg, ubg, f)."""
    opt = data.prob.options
    K = data.grid.K
    base = _ipopt_options(opt)
    if max_iter is not None:
        base["max_iter"] = int(max_iter)
    stages = stages if stages is not None else homotopy_stages(opt, data)
    status, sol = "", None
    lam_x = lam_g = None
    warm_ok = lam is not None  # multipliers handed in by the caller come from converged solves
    if lam is not None:
        lam_x, lam_g = lam
    screen_distance = float(opt.collision_screen_distance)
    kinds = screening.row_kinds(win) if screen_distance > 0 else None
    si, rescreens = 0, 0
    while si < len(stages):
        expo, hard, pen, hom = stages[si]
        lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, expo, hard, pen, hom)
        args = dict(lbx=_vec(lbw), ubx=_vec(ubw), lbg=_vec(lbg), ubg=_vec(ubg), p=_vec(Pm))
        last_stage = si == len(stages) - 1
        if z0 is None:
            args["x0"] = _vec(W0)
            o, tag = dict(base), "main"
        elif lam_x is not None and warm_ok and _start_violation(
                wd, data, K, threads, win, z0, args, hom) <= opt.final_warm_start_max_violation:
            # the previous stage converged near this one's feasible set: primal-dual warm start
            # with a small barrier
            args["x0"] = np.clip(z0, args["lbx"], args["ubx"])
            args["lam_x0"], args["lam_g0"] = lam_x, lam_g
            o, tag = _warm_options(base), "warm"
        else:
            # the previous stage stopped early (the capped surrogate guide): its multipliers are not
            # near optimal, and a primal-dual warm start with a small barrier then crawls along the
            # bounds for hundreds of iterations; hand over the primal point only, barrier from scratch
            args["x0"] = np.clip(z0, args["lbx"], args["ubx"])
            o, tag = dict(base), "main"
        if not last_stage:  # the surrogate stage only guides: cap its iterations
            o["max_iter"] = min(int(o["max_iter"]), GUIDE_STAGE_MAX_ITER)
            o.update(GUIDE_STAGE_TOLERANCES)
            tag = "guide" if tag == "main" else f"{tag} guide"
        if last_stage and not rescreens:   # a rescreened final starts from its first try, not the guide
            run.guide_point = None if z0 is None else np.array(z0, float)   # for Options.final_cold_retry
        hessian = opt.final_hessian if last_stage else opt.guide_hessian
        if hessian == "exact" and kinds is None:
            hessian = "exact_full"   # every pair in the NLP: the split would evaluate each at every knot
        nlp = get_nlp(wd, data.structure, K, threads)
        if z0 is not None and hom is True:
            args["x0"] = np.clip(_feasible_slacks(win, nlp, K, args["x0"], args["p"]), args["lbx"], args["ubx"])
        rows = active_rows(args["lbg"], args["ubg"])
        screen = None
        if kinds is not None:
            screen = _screen(kinds, win, nlp, K, args, Pm, screen_distance)
            rows = np.setdiff1d(rows, screen.rows, assume_unique=True)
        nlp, s = get_solver(wd, data.structure, K, o, threads, tag, hessian, rows,
                            transient=screen is not None)
        kind = "surrogate guide" if not last_stage else "final"
        stage_name = f"{label}{kind}" + (f" (rescreened {rescreens})" if rescreens else "")
        cb = _CALLBACKS[id(s)]
        cb.sink = run.sink(stage_name, args["lbg"][rows], args["ubg"][rows], stall=last_stage)
        call = dict(args, lbg=args["lbg"][rows], ubg=args["ubg"][rows])
        if "lam_g0" in call:
            call["lam_g0"] = np.asarray(call["lam_g0"])[rows]
        t0 = time.perf_counter()
        try:
            sol = s(**call)
        finally:
            cb.sink = None
        dt = time.perf_counter() - t0
        st = s.stats()
        ipopt_status = st.get("return_status", "")
        feasible_best = run.best is not None and run.best[1] is not None
        status = stage_status(ipopt_status, opt, last_stage=last_stage, stalled=run.stalled,
                              feasible_best=feasible_best, timed_out=run.timed_out)
        warm_ok = _converged(status)
        reg = np.asarray(st.get("iterations", {}).get("regularization_size", []), float)
        start = "warm" if tag.startswith("warm") else ("cold" if z0 is not None else "keyframes")
        record = {"stage": stage_name, "exponent": expo, "hard": hard, "status": status,
                  "ipopt_status": ipopt_status, "start": start,
                  "iterations": int(st.get("iter_count", 0)), "time": dt, "timing": _timing_split(st, dt),
                  "regularised_iterations": int(np.count_nonzero(reg > 0)), "rows": int(len(rows))}
        run.stages.append(record)
        z0 = np.array(sol["x"]).ravel()
        lam_x = np.array(sol["lam_x"]).ravel()
        lam_g = np.array(sol["lam_g"]).ravel()
        f_sol = float(sol["f"])
        if status in _BEST_ITERATE_STATUSES and feasible_best:
            f_sol, z0, lam_x, lam_g = run.best  # the best feasible iterate, not ipopt's last one
        lam_g = _scatter(lam_g, rows, nlp.ngg)  # multipliers of the switched-off rows are 0
        if run.timed_out:
            status = f"time limit {opt.time_limit:.0f} s reached"
            break
        if screen is not None and not screen.empty:
            lam_x[screen.slacks] = 0.0   # pinned by the screen, not by the problem
            violated = _screened_rows_violated(screen, kinds, win, nlp, K, z0, args, Pm, screen_distance)
            record["screened_rows"], record["screened_rows_violated"] = int(screen.rows.size), violated
            if violated and rescreens < MAX_RESCREENS:
                # a screened row does not hold at the result: the same stage again, screened anew
                record["status"] = f"{status}; {violated} screened rows violated, solved again"
                rescreens += 1
                continue
        si, rescreens = si + 1, 0
    return z0, lam_x, lam_g, status, nlp, args, Pm, lbg, ubg, f_sol


#: how many times a stage is solved again because a screened collision row does not hold at its
#: result (Options.collision_screen_distance); after that its result is kept as it is and the
#: checks on the whole problem (penetration) judge it
MAX_RESCREENS = 2


def _self_margin(win: Window, Pm: np.ndarray) -> np.ndarray:
    return np.asarray(Pm, float)[win.P["self_margin"], :].ravel()


def _screen(kinds, win: Window, nlp: AssembledNLP, K: int, args: dict, Pm: np.ndarray,
            distance: float) -> "screening.Screen":
    """The collision rows of a stage left out at its start point; their slacks are pinned at 0."""
    _, g = nlp.F_nlp(args["x0"], args["p"])
    screen = screening.far_rows(kinds, win, K, np.array(g).ravel(), args["x0"], args["lbg"],
                                _self_margin(win, Pm), distance)
    for key in ("lbx", "ubx", "x0"):
        args[key] = np.array(args[key], float)
        args[key][screen.slacks] = 0.0
    return screen


def _screened_rows_violated(screen, kinds, win: Window, nlp: AssembledNLP, K: int, z, args: dict, Pm: np.ndarray,
                        distance: float) -> int:
    _, g = nlp.F_nlp(z, args["p"])
    return screening.violated_rows(screen, kinds, win, K, np.array(g).ravel(), z, args["lbg"], _self_margin(win, Pm),
                               distance)


#: stage statuses under which the stage returns its best feasible iterate, not ipopt's last one
_BEST_ITERATE_STATUSES = (STALLED_STATUS, CAPPED_FEASIBLE_STATUS, FEASIBLE_BEFORE_STOP_STATUS)


def stage_status(ipopt_status: str, opt, last_stage: bool, stalled: bool, feasible_best: bool,
                 timed_out: bool) -> str:
    """A stage's status from ipopt's: the stall stop, or a final stage that ipopt ended at its cap
    or early (STOPPED_EARLY_STATUSES) after a feasible iterate, is renamed so that the stage counts as
    converged on that iterate (Options.accept_feasible_at_cap / accept_feasible_at_solver_stop)."""
    if stalled:
        return STALLED_STATUS
    if not last_stage or not feasible_best or timed_out:
        return ipopt_status
    if ipopt_status == "Maximum_Iterations_Exceeded" and opt.accept_feasible_at_cap:
        return CAPPED_FEASIBLE_STATUS
    if ipopt_status in STOPPED_EARLY_STATUSES and opt.accept_feasible_at_solver_stop:
        return FEASIBLE_BEFORE_STOP_STATUS
    return ipopt_status


def _start_violation(wd, data: ProblemData, K: int, threads: int, win, z0, args: dict, hom: bool) -> float:
    """Largest violation of a stage's rows at the previous stage's point (slacks raised as the stage
    itself will raise them)."""
    nlp = get_nlp(wd, data.structure, K, threads)
    x0 = np.clip(z0, args["lbx"], args["ubx"])
    if hom is True:
        x0 = np.clip(_feasible_slacks(win, nlp, K, x0, args["p"]), args["lbx"], args["ubx"])
    _, g = nlp.F_nlp(x0, args["p"])
    g = np.array(g).ravel()
    return float(np.max(np.maximum(np.maximum(args["lbg"] - g, g - args["ubg"]), 0.0), initial=0.0))


def _scatter(values: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[rows] = np.asarray(values, float).ravel()
    return out


def _feasible_slacks(win: Window, nlp: AssembledNLP, K: int, z: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Raise each homotopy slack so its surrogate row holds at ``z``.

    A stage with a sharper surrogate (higher exponent) starts from the previous stage's point,
    where ``F_new - 1 + s_old`` is negative wherever a sphere is inside the sharper surrogate but
    was outside the smoother one: a spurious violation of order 1 that ipopt then spends
    iterations removing (S2 subtask 1: scaled start infeasibility 0.86 -> 0.05 with this).  The slack is free and
    only penalised, so setting it to ``max(s_old, 1 - F_new)`` costs nothing and starts the stage
    feasible in those rows."""
    if not win.st.obj_pairs:
        return z
    _, g = nlp.F_nlp(z, p)
    G = np.array(g).reshape(K, win.G.n)
    Z = np.array(z, float).reshape(K + 1, win.W.n).copy()
    rows = [win.G[f"c{i} homotopy surrogate"].start for i in range(len(win.st.obj_pairs))]
    sl = win.W["slack"]
    Z[:K, sl] -= np.minimum(G[:, rows], 0.0)
    return Z.ravel()


def _timing_split(st: dict, wall: float) -> dict:
    """Where a stage's wall time went: CasADi evaluation of the assembled functions (value,
    gradient, Jacobian, Hessian) vs the rest (ipopt's linear algebra = MUMPS, plus the Python
    iteration callback), from CasADi's per-function timers."""
    ev = {k[len("t_wall_"):]: float(v) for k, v in st.items()
          if k.startswith("t_wall_nlp_") and isinstance(v, (int, float))}
    calls = {k[len("n_call_"):]: int(v) for k, v in st.items()
             if k.startswith("n_call_nlp_") and isinstance(v, (int, float))}
    t_eval = sum(ev.values())
    return {"wall": wall, "eval": t_eval, "eval_by_function": ev, "calls": calls,
            "callback": float(st.get("t_wall_callback_fun", 0.0)),
            "rest": max(wall - t_eval - float(st.get("t_wall_callback_fun", 0.0)), 0.0)}


def _with_cold_retry(run: _Run, data: ProblemData, win, wd, threads, label: str, res: tuple) -> tuple:
    """``res`` of :func:`_run_stages`, or, when its final stage started warm and failed and
    ``Options.final_cold_retry`` is on, the final stage solved again from the guide's primal point
    with the barrier from scratch (its iterations count in the same solve)."""
    opt = data.prob.options
    last = run.stages[-1] if run.stages else {}
    if (_converged(res[3]) or not opt.final_cold_retry or run.timed_out or run.guide_point is None
            or last.get("start") != "warm"):
        return res
    return _run_stages(run, data, win, wd, threads, label + "cold retry ", z0=run.guide_point,
                       stages=[homotopy_stages(opt, data)[-1]])


def _converged(status: str) -> bool:
    return status in ("Solve_Succeeded", "Solved_To_Acceptable_Level") or status.startswith(_BEST_ITERATE_STATUSES)


def solve(prob: Problem, model: G1Model | None = None, threads: int = 2, progress=None) -> TOResult:
    """Solve the TO.  Raises ProblemError on invalid input (before any solve).

    ``progress(Progress)`` is called once per ipopt iteration (iteration, objective, constraint
    violation, stage, elapsed time).  Problems with several subtasks are solved subtask by subtask
    first (each segment starts at rest in the state the previous one ended in, see
    :func:`segments`); the segments are stitched into the whole horizon, which is then polished
    for at most ``Options.polish_iterations``; if the polish does not converge, the stitched
    trajectory (feasible for the whole problem, at rest at subtask boundaries) is kept.
    """
    model = model or default_model()
    t_start = time.perf_counter()
    validate_problem(prob, model)
    opt = prob.options
    data = ProblemData(prob, model)
    win, wd = get_window(model, data.structure)
    run = _Run(prob, progress, t_start)
    segs = segments(prob) if opt.subtask_segments and data.grid.K > SEGMENT_MIN_KNOTS else []
    t_failed = 0.0  # where a failed segment starts on the plan's clock
    if len(segs) <= 1:
        get_nlp(wd, data.structure, data.grid.K, threads)  # assemble before timing
        build_time = time.perf_counter() - t_start
        z, _, _, status, nlp, args, Pm, lbg, ubg, f = _with_cold_retry(
            run, data, win, wd, threads, "", _run_stages(run, data, win, wd, threads, ""))
        converged = _converged(status)
    else:
        build_time = time.perf_counter() - t_start
        x_init = np.asarray(prob.initial_configuration, float)
        poses = _initial_poses(prob)
        parts, converged, status, grips = [], True, "", {}
        for i, (t0, t1) in enumerate(segs):
            sp = segment_problem(prob, t0, t1, x_init, poses, grips)
            moving = segment_moving(data.moving, sp) if opt.segment_moving_objects else data.moving
            sd = ProblemData(sp, model, moving=moving, pairs=data.pairs, stand=data.x_init,
                             env_pairs=[e for e in data.env_pairs if e[0] in moving])
            swin, swd = (win, wd) if sd.structure == data.structure else get_window(model, sd.structure)
            where = f"subtask {sp.phases[0].subtask_index} ({t0:.1f}-{t1:.1f} s)"
            res = _with_cold_retry(run, sd, swin, swd, threads, where + " ",
                                   _run_stages(run, sd, swin, swd, threads, where + " "))
            parts.append((sd, res, swin))
            if not _converged(res[3]):
                converged = False
                status = f"{res[3]} in {where}"
                break
            Wm = res[0].reshape(sd.grid.K + 1, swin.W.n).T
            x_init = Wm[swin.W["x"], sd.grid.K - 1].copy()
            poses = _poses_at_end(swin, sd, Wm, poses)
            grips = _grips_at_end(swin, sd, res[6])
        if converged:
            status = "; ".join(f"{kind} ({', '.join(names)})" for kind in _BEST_ITERATE_STATUSES
                               if (names := [st["stage"].strip() for st in run.stages if st["status"] == kind])) \
                or "Solve_Succeeded"
            z_st, lam_st = _stitch(win, data, parts)
            z = z_st
            nlp, args, Pm, lbg, ubg, f = _evaluate_stitched(data, win, wd, threads, z_st)
            if opt.polish_iterations > 0 and not run.timed_out:
                zp, _, _, pst, nlp, args_p, Pm_p, lbg_p, ubg_p, fp = _run_stages(
                    run, data, win, wd, threads, "whole-horizon polish ", z0=z_st, lam=lam_st,
                    stages=[homotopy_stages(opt, data)[-1]], max_iter=opt.polish_iterations)
                if _converged(pst):
                    z, f, args, Pm, lbg, ubg = zp, fp, args_p, Pm_p, lbg_p, ubg_p
                    status = pst
                else:
                    status = f"{status}; whole-horizon polish: {pst} (stitched subtask solution kept)"
        else:
            prefix = None if run.timed_out else _solved_prefix(prob, model, data, win, wd, threads, segs, parts)
            if prefix is not None:   # the solved subtasks and the failed one's iterate, from 0
                data, z, nlp, args, Pm, lbg, ubg, f = prefix
            else:  # the failed segment's iterate alone, on its own clock (shifted back below)
                data, (z, _, _, _, nlp, args, Pm, lbg, ubg, f), win = parts[-1]
                t_failed = segs[len(parts) - 1][0]
    solve_time = time.perf_counter() - t_start - build_time
    res = extract(model, data, win, nlp, z, args, Pm, lbg, ubg)
    stats = res.stats
    stats.converged = converged
    stats.status = status
    stats.iterations = run.iterations
    stats.build_time = build_time
    stats.solve_time = solve_time
    stats.cost = f
    stats.stages = run.stages
    stats.peak_memory_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    stats.checks = run_checks(model, data, res)
    if t_failed:
        on_plan_clock(res, t_failed)
    tol_ok = stats.max_constraint_violation.value <= 1e-2
    stats.success = bool(converged and tol_ok and all(c["ok"] for c in stats.checks.values()))
    res.densify(opt.output_rate)
    res.data = data
    return res


def get_nlp(wd, structure, K: int, threads: int = 2) -> AssembledNLP:
    nkey = (structure, K)
    if nkey not in _NLPS:
        _NLPS[nkey] = AssembledNLP(wd, K, threads=threads)
    return _NLPS[nkey]


#: a rest point ends a double stance of at least this long (s): time to come to rest in it
REST_MIN_STANCE = 0.4
#: neither piece of a subtask cut at a rest point is shorter than this (s)
REST_MIN_SEGMENT = 0.8


def _grip(ph) -> tuple:
    return tuple(sorted((h, c.object_id) for h, c in ph.contacts.items() if h in HANDS))


def _double_stance(ph) -> bool:
    return ph.phase_type == "stance" and all(f in ph.contacts for f in FEET)


def rest_points(prob: Problem) -> list:
    """Times inside a subtask at which its segment can be cut with the robot at rest: the end of a
    double-stance phase of at least ``REST_MIN_STANCE`` after which walking starts or the hands
    take a new hold (not a release), with no object changing its motion mode there and no push
    going on across it (a hand on a sliding or rolling object on both sides), and both pieces of
    the subtask at least ``REST_MIN_SEGMENT`` long.  Every segment ends at rest (robot and objects), so a cut
    there only asks for a stop the schedule already has room for.

    Used when ``Options.rest_segments`` is on (off by default).  Tried on S1's carry subtask (lift
    in double stance, six steps, set down, release, retract: one NLP of 64 knots that hits its
    guide's iteration cap): the 0.8 s lift piece converges but ends with the box barely lifted,
    and the carry piece from there did not converge (docs/to.md, session 9)."""
    out = []
    phases = prob.phases
    for sub in sorted({ph.subtask_index for ph in phases}):
        idx = [i for i, ph in enumerate(phases) if ph.subtask_index == sub]
        t_start, t_end = phases[idx[0]].start, phases[idx[-1]].end
        last = t_start
        for i in idx[:-1]:
            ph, nx = phases[i], phases[i + 1]
            if not (_double_stance(ph) and ph.end - ph.start >= REST_MIN_STANCE - 1e-9):
                continue
            if not (nx.phase_type == "walking" or _grip(nx) != _grip(ph)):
                continue
            if prob.options.dt_reach > 0 and reaches(phases, i):
                continue  # the reach's spacing needs the grasp after it in the same segment
            if set(_grip(ph)) - set(_grip(nx)):
                # a release: the hand is still at the contact at its first free knot, where the
                # hand-object pairs are off; a segment starting there has them on (S1's release
                # piece: left wrist 5 cm in the box at its fixed first knot, infeasible)
                continue
            modes = {o: m.mode for o, m in ph.objects.items()}
            if modes != {o: m.mode for o, m in nx.objects.items()}:
                continue
            held = {c.object_id for h, c in ph.contacts.items() if h in HANDS}
            held &= {c.object_id for h, c in nx.contacts.items() if h in HANDS}
            if any(modes.get(o) in ("supported", "rolling") for o in held):
                continue  # a push goes on across it: the pushed object would have to stop there
            if ph.end - last >= REST_MIN_SEGMENT - 1e-9 and t_end - ph.end >= REST_MIN_SEGMENT - 1e-9:
                out.append(ph.end)
                last = ph.end
    return out


def segments(prob: Problem, rest: bool | None = None) -> list:
    """[(t0, t1)] of the pieces solved one after the other: consecutive subtasks (phase boundaries
    where the subtask index changes), each also cut at its :func:`rest_points` when ``rest`` (by
    default ``Options.rest_segments``)."""
    rest = prob.options.rest_segments if rest is None else rest
    cuts = set(rest_points(prob)) if rest else set()
    phases = prob.phases
    out, t0, deferred = [], 0.0, False
    for i, ph in enumerate(phases):
        last = i == len(phases) - 1
        if last or phases[i + 1].subtask_index != ph.subtask_index or ph.end in cuts or deferred:
            deferred = False
            if (not last and prob.options.lift_with_previous_segment and _lifts(phases, i + 1)
                    and i + 2 < len(phases) and phases[i + 2].subtask_index == phases[i + 1].subtask_index):
                deferred = True   # the lift's phase goes with this segment (Options.lift_with_previous_segment)
                continue
            out.append((t0, ph.end))
            t0 = ph.end
    return out


def segment_moving(moving: list, sp: Problem) -> list:
    """The objects of ``moving`` (the whole problem's moving objects, in its order) that segment
    ``sp`` moves, touches with a hand or attaches others to (``Options.segment_moving_objects``);
    the rest stand in it as scene objects at the poses ``sp`` gives them."""
    used = set()
    for ph in sp.phases:
        for oid, mo in ph.objects.items():
            used.update((oid, mo.attached_to) if mo.attached_to else (oid,))
        used.update(c.object_id for h, c in ph.contacts.items() if h in HANDS)
    return [oid for oid in moving if oid in used]


def segment_problem(prob: Problem, t0: float, t1: float, x_init, poses: dict, grips: dict | None = None) -> Problem:
    """The sub-problem on [t0, t1], shifted to start at 0, starting at rest in ``x_init`` with the
    objects at ``poses`` (p, rpy).

    ``grips`` (hand -> (object id, contact point, normal), both in the object's frame) are the
    grips held at t0, as the previous segment had them (:func:`_grips_at_end`).  A segment cut at a
    rest point starts with the object already moved: the schedule's contact points (world, at the
    object's pose when the grip began) are re-expressed at its pose at t0 for the phases that go on
    holding it, so the grip stays where it was on the object.  Keyframes of the segment's subtasks
    after t1 stay in (they only anchor the warm start's nominal, see ``ProblemData``).  A segment of
    one subtask takes that subtask's ``Options.subtask_options``."""
    from dataclasses import replace

    from .model import rot_to_quat_xyzw

    phases = [replace(ph, start=ph.start - t0, end=ph.end - t0) for ph in prob.phases
              if ph.start >= t0 - 1e-9 and ph.end <= t1 + 1e-9]
    for h, (oid, loc, n) in (grips or {}).items():
        pose = np.asarray(poses[oid], float)
        R = rpy_to_rot(pose[3:])
        pos_w = tuple(float(v) for v in pose[:3] + R @ np.asarray(loc, float))
        n_w = tuple(float(v) for v in R @ np.asarray(n, float))
        for i, ph in enumerate(phases):
            c = ph.contacts.get(h)
            if c is None or c.object_id != oid:
                break
            phases[i] = replace(ph, contacts={**ph.contacts, h: replace(c, position=pos_w, normal=n_w)})
    subs = {ph.subtask_index for ph in phases}
    kfs = [replace(kf, time=prob.keyframe_time(kf) - t0) for kf in prob.keyframes if kf.subtask_index in subs]
    goals = []
    for g in prob.placement_goals:
        tg = prob.duration if g.time is None else g.time
        if t0 + 1e-9 < tg <= t1 + 1e-9:
            goals.append(replace(g, time=tg - t0))
    objs = []
    for o in prob.objects:
        pose = poses[o.id]
        objs.append(replace(o, position=tuple(pose[:3]), quat_xyzw=tuple(rot_to_quat_xyzw(rpy_to_rot(pose[3:])))))
    options = prob.options
    if len(subs) == 1 and (over := options.subtask_options.get(next(iter(subs)))):
        options = options.replaced(**over)
    return Problem(objects=objs, keyframes=kfs, phases=phases, initial_configuration=tuple(x_init),
                   placement_goals=goals, options=options, name=f"{prob.name}[{t0:.1f}-{t1:.1f}]")


def _poses_at_end(win: Window, sd: ProblemData, Wm: np.ndarray, poses: dict) -> dict:
    """Object poses a segment hands to the next one: an object that never moved in it keeps its
    pose exactly; one resting on a support at the end gets the support's height and no tilt.

    Why: the solver's copy of a pose is only as good as the row tolerance at each knot (S1's
    unmoved box drifted 0.4 mm over subtask 0), and the next segment fixes its first knot to it,
    where the support rows are then violated by a constant above ``constr_tol``: subtask 1 ran to
    its iteration caps at a violation of 2.8e-4 it could never remove."""
    out = dict(poses)
    k = sd.grid.K - 1
    for oid, j in sd.midx.items():
        if all(sd.obj_mode(i, oid) == "fixed" for i in range(sd.grid.K)):
            continue
        pose = Wm[win.W[f"o{j}_pose"], k].copy()
        mo = sd.prob.phases[sd.grid.phase[k]].objects.get(oid)
        if sd.obj_mode(k, oid) in ("supported", "rolling") and mo is not None:
            pose[2] = sd.rest_height(oid, mo.support)
            pose[3:5] = 0.0
        out[oid] = pose
    return out


def _grips_at_end(win: Window, sd: ProblemData, Pm: np.ndarray) -> dict:
    """hand -> (object id, contact point, normal in the object's frame) of the grips held at the
    segment's last knot (the parameters its rows used)."""
    out = {}
    k = sd.grid.K - 1
    for h in HANDS:
        c = sd.contact(k, h)
        if c is None or c.object_id not in sd.midx:
            continue
        out[h] = (c.object_id, Pm[win.P[f"{h}_loc"], k].copy(), Pm[win.P[f"{h}_n"], k].copy())
    return out


def on_plan_clock(res: TOResult, t0: float) -> None:
    """Moves a segment's result, whose problem starts at 0, to the plan's clock where the segment
    starts at ``t0``: knot times, the violations' and penetration's times and the checks' places.
    Why: a failed S2 carry (3.0-10.6 s) reported its worst violation "at t=0.00 s" and its
    penetration at 6.2 s, 3 s before where they were (docs/to.md, session 33)."""
    res.t_knots = np.asarray(res.t_knots, float) + t0
    stats = res.stats
    for name in ("max_dynamics_violation", "max_contact_violation", "max_constraint_violation"):
        v = getattr(stats, name)
        setattr(stats, name, Violation(v.value, v.time + t0, v.constraint))
    stats.max_penetration_time += t0
    shift = lambda m: f"t={float(m.group(1)) + t0:.2f}"  # noqa: E731
    for check in (stats.checks or {}).values():
        for key in ("where", "between_knots_where", "held_object_forearm_where"):
            if isinstance(check.get(key), str):
                check[key] = re.sub(r"t=(-?\d+(?:\.\d+)?)", shift, check[key])


def _solved_prefix(prob: Problem, model: G1Model, data: ProblemData, win: Window, wd, threads: int, segs: list,
                   parts: list):
    """(data, z, nlp, args, Pm, lbg, ubg, f) of a failed segmented solve on [0, end of the failed
    segment]: the segments that converged stitched with the failed one's last iterate, evaluated on
    that prefix of the problem; None with nothing solved before the failure, or if the segments' grids
    do not make the prefix's.

    Why: a failed S2 from prompts handed back only its push segment (10.6-20.2 s), so the pick and
    carry it had solved were lost and the failure could not be seen in context (session 34)."""
    if len(parts) < 2:
        return None
    sp = segment_problem(prob, 0.0, segs[len(parts) - 1][1], prob.initial_configuration, _initial_poses(prob))
    pd = ProblemData(sp, model, moving=data.moving, pairs=data.pairs, stand=data.x_init, env_pairs=data.env_pairs)
    try:
        z, _ = _stitch(win, pd, parts)
    except RuntimeError:
        return None
    nlp, args, Pm, lbg, ubg, f = _evaluate_stitched(pd, win, wd, threads, z)
    return pd, z, nlp, args, Pm, lbg, ubg, f


def _evaluate_stitched(data: ProblemData, win: Window, wd, threads: int, z: np.ndarray):
    """(nlp, args, Pm, lbg, ubg, objective) of stitched segments ``z`` on ``data``'s grid: the final
    homotopy stage's rows, with feet on moved objects standing on the objects' solved poses."""
    Zm = z.reshape(data.grid.K + 1, win.W.n)
    data.use_solved_support_poses({oid: Zm[:data.grid.K, win.W[f"o{j}_pose"]] for oid, j in data.midx.items()})
    lbw, ubw, lbg, ubg, Pm, _ = data.fill(win, *homotopy_stages(data.prob.options, data)[-1])
    nlp = get_nlp(wd, data.structure, data.grid.K, threads)
    args = dict(lbx=_vec(lbw), ubx=_vec(ubw), lbg=_vec(lbg), ubg=_vec(ubg), p=_vec(Pm))
    return nlp, args, Pm, lbg, ubg, float(nlp.F_nlp(z, args["p"])[0])


def _initial_poses(prob: Problem) -> dict:
    """Object id -> (position, rpy) where ``prob`` starts it."""
    return {o.id: np.concatenate([np.asarray(o.position, float), o.rpy()]) for o in prob.objects}


def _stitch(win: Window, data: ProblemData, parts) -> tuple:
    """Concatenate segment solutions (primal and multipliers) on the whole-horizon grid.  A segment
    solved on its own window (``Options.segment_moving_objects``) is mapped onto the whole one
    (:func:`_onto_window`); its constraint multipliers are not, so the stitch then hands back no
    multipliers (a polish after it starts cold)."""
    nw, ng = win.W.n, win.G.n
    zs, lxs, lgs = [], [], []
    same = all(swin is win for _, _, swin in parts)
    for i, (sd, res, swin) in enumerate(parts):
        K = sd.grid.K
        n = K if i == len(parts) - 1 else K - 1  # a segment's end knot is the next one's first knot
        zs.append(_onto_window(win, data, swin, sd, res[0].reshape(K + 1, swin.W.n)[:n], primal=True))
        lxs.append(_onto_window(win, data, swin, sd, res[1].reshape(K + 1, swin.W.n)[:n], primal=False))
        if same:
            lgs.append(res[2].reshape(K, ng)[:n])
    Z = np.vstack(zs + [np.zeros((1, nw))])
    _unwrap_object_angles(win, data, Z)
    if Z.shape[0] != data.grid.K + 1:
        raise RuntimeError(f"stitched {Z.shape[0] - 1} knots, the whole horizon has {data.grid.K}")
    if not same:
        return Z.ravel(), None
    LX = np.vstack(lxs + [np.zeros((1, nw))])
    LG = np.vstack(lgs)
    return Z.ravel(), (LX.ravel(), LG.ravel())


def _onto_window(win: Window, data: ProblemData, swin: Window, sd: ProblemData, Zs: np.ndarray,
                 primal: bool) -> np.ndarray:
    """Knot rows ``Zs`` of segment ``sd``'s window ``swin`` as rows of the whole problem's window
    ``win``: each moving object's blocks from the segment's index of that object; an object the
    segment left standing (not among its moving ones) holds the pose the segment gave it with zero
    velocity and support forces (as the whole problem's bounds have a "fixed" object), and zero
    multipliers (``primal`` False)."""
    if swin is win:
        return Zs
    out = np.zeros((Zs.shape[0], win.W.n))
    for name, sl in win.W.blocks.items():
        if (obj_block := re.fullmatch(r"o(\d+)(_\w+)", name)) is not None:   # o{j}_pose, o{j}_vel, o{j}_us
            oid, kind = data.moving[int(obj_block[1])], obj_block[2]
            if oid in sd.midx:
                out[:, sl] = Zs[:, swin.W[f"o{sd.midx[oid]}{kind}"]]
            elif primal and kind == "_pose":
                o = sd.prob.object(oid)
                out[:, sl] = np.concatenate([np.asarray(o.position, float), o.rpy()])
        else:
            out[:, sl] = Zs[:, swin.W[name]]
    return out


def _unwrap_object_angles(win: Window, data: ProblemData, Z: np.ndarray) -> None:
    """Make the objects' roll, pitch and yaw continuous across segment joins (in place, knot rows of
    ``Z``). Why: a segment starts its objects at poses handed over as quaternions, so an angle past
    +-pi comes back wrapped by 2 pi; S2 5.0 kg at yaw -1.2 (session 41) stitched the box's yaw from
    -3.143 to 3.140 at 8.8 s, and the whole horizon's kinematic integration row read a violation of
    6.28 there. Within a segment no knot-to-knot turn comes near pi."""
    K = data.grid.K
    for j in data.midx.values():
        sl = win.W[f"o{j}_pose"]
        cols = np.arange(sl.start, sl.stop)[3:6]
        Z[:K, cols] = np.unwrap(Z[:K, cols], axis=0)


def _vec(A: np.ndarray) -> np.ndarray:
    return np.asarray(A, float).ravel(order="F")


def _readable(name: str, data: ProblemData, win: Window) -> str:
    m = re.match(r"^o(\d+) (.*)$", name)
    if m:
        return f"{data.moving[int(m.group(1))]} {m.group(2)}"
    m = re.match(r"^c(\d+) (.*)$", name)
    if m:
        s, (oid, pi) = data.pairs[int(m.group(1))]
        return f"{m.group(2)}: {data.model.spheres[s].name} vs {oid}[{pi}]"
    m = re.match(r"^e(\d+) (.*)$", name)
    if m:
        oid, pt, (po, pi) = data.env_pairs[int(m.group(1))]
        return f"{m.group(2)}: {oid} at ({pt[0]:+.2f}, {pt[1]:+.2f}, {pt[2]:+.2f}) vs {po}[{pi}]"
    m = re.match(r"^self (\d+) (\d+)$", name)
    if m:
        return f"self-collision {data.model.spheres[int(m.group(1))].name} vs {data.model.spheres[int(m.group(2))].name}"
    for limb in LIMBS:
        name = name.replace(limb, limb.replace("_", " "))
    return name


def extract(model: G1Model, data: ProblemData, win: Window, nlp: AssembledNLP, z, args, Pm, lbg, ubg) -> TOResult:
    K = data.grid.K
    W = win.W
    Wm = z.reshape(K + 1, W.n).T[:, :K]
    t = data.grid.t
    X = Wm[W["x"]].T.copy()
    XD = Wm[W["xd"]].T.copy()
    mg = model.mass * 9.81
    # constraint violations with location
    f, g = nlp.F_nlp(z, args["p"])
    G = np.array(g).reshape(K, win.G.n).T
    viol = np.maximum(np.maximum(lbg - G, G - ubg), 0.0)
    names = win.G.row_names()
    stats = SolverStats(n_knots=K, n_variables=nlp.nz, n_constraints=nlp.ngg)

    def worst(filter_fn):
        best = Violation()
        for r, nm in enumerate(names):
            if not filter_fn(nm):
                continue
            k = int(np.argmax(viol[r]))
            if viol[r, k] > best.value:
                best = Violation(float(viol[r, k]), float(t[k]), _readable(nm, data, win))
        return best

    is_dyn = lambda nm: any(nm.endswith(d) for d in DYNAMICS_ROWS)
    is_col = lambda nm: ("collision" in nm or "surrogate" in nm or nm.startswith("self") or nm == "floor clearance")
    stats.max_dynamics_violation = worst(is_dyn)
    stats.max_contact_violation = worst(lambda nm: not is_dyn(nm) and not is_col(nm))
    stats.max_constraint_violation = worst(lambda nm: "surrogate" not in nm)
    # contact wrenches (world, on the robot)
    forces, torques, points, corners, objs, normals = {}, {}, {}, {}, {}, {}
    nums = [model.numeric(X[k]) for k in range(K)]
    for limb in LIMBS:
        F = np.zeros((K, 3))
        T = np.zeros((K, 3))
        Pp = np.zeros((K, 3))
        C = np.zeros((K, 4, 3))
        Nn = np.zeros((K, 3))
        ob = []
        for k in range(K):
            pt, R = nums[k]["limbs"][limb]
            Pp[k] = pt
            c = data.contact(k, limb)
            ob.append(c.object_id if c is not None else "")
            if limb in FEET:
                u = Wm[W[f"u_{limb}"], k].reshape(4, 3) * mg
                C[k] = u
                F[k] = u.sum(0)
                jid = model.limb_joint[limb]
                tree = nums[k]["tree"]
                for i in range(4):
                    ci = tree["p"][jid] + tree["R"][jid] @ data.sole_force_points[i]
                    T[k] += np.cross(ci - pt, u[i])
            else:
                F[k] = Wm[W[f"u_{limb}"], k] * mg
                T[k] = Wm[W[f"tau_{limb}"], k] * mg  # patch moment about the hand point
                if c is not None:
                    n = Pm[win.P[f"{limb}_n"], k]
                    sel = Pm[win.P[f"{limb}_sel"], k]
                    Rs = sel[0] * np.eye(3)
                    for j in range(len(data.moving)):
                        Rs = Rs + sel[j + 1] * rpy_to_rot(Wm[W[f"o{j}_pose"], k][3:])
                    Nn[k] = Rs @ n
                    Pp[k] = pt - data.prob.options.hand_standoff * Nn[k]  # the force's point, on the surface
        forces[limb], torques[limb], points[limb], corners[limb], objs[limb], normals[limb] = F, T, Pp, C, ob, Nn
    h = np.stack([np.concatenate([Wm[W["comd"], k], Wm[W["kk"], k]]) * model.mass for k in range(K)])
    obj_pose = {oid: Wm[W[f"o{j}_pose"]].T.copy() for oid, j in data.midx.items()}
    obj_vel = {oid: Wm[W[f"o{j}_vel"]].T.copy() for oid, j in data.midx.items()}
    res = TOResult(
        joint_names=list(model.joint_names), limbs=list(LIMBS), object_ids=list(data.moving),
        t_knots=t.copy(), x_knots=X, xd_knots=XD, com_knots=Wm[W["com"]].T.copy(), h_knots=h,
        forces_knots=forces, torques_knots=torques, points_knots=points,
        corner_forces_knots={f: corners[f] for f in FEET}, contact_objects_knots=objs,
        object_pose_knots=obj_pose, object_vel_knots=obj_vel, penetration_knots=np.zeros(K), stats=stats,
        normals_knots={h_: normals[h_] for h_ in HANDS})
    pen, worst_pen, wk = penetration_per_knot(model, data, res)
    res.penetration_knots = pen
    stats.max_penetration = float(worst_pen)
    stats.max_penetration_time = float(t[wk])
    return res
