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

import re
import resource
import time

import casadi as ca
import numpy as np

from .assembly import AssembledNLP, WindowDerivatives
from .checks import penetration_per_knot, run_checks
from .discretize import ProblemData
from .model import FEET, HANDS, LIMBS, SOLE_CORNERS, G1Model, rpy_to_rot
from .problem import TO_NOT_CONVERGED, Problem, validate_problem
from .result import SolverStats, TOResult, Violation
from .transcription import Window

_WINDOWS: dict = {}
_NLPS: dict = {}
_SOLVERS: dict = {}
_MODEL: list = []
#: iteration cap of the homotopy guide stage (ellipsoid surrogate); the final stage is not capped
GUIDE_STAGE_MAX_ITER = 80

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


def get_solver(wd, structure, K: int, ipopt_opts: dict, threads: int = 2):
    nkey = (structure, K)
    if nkey not in _NLPS:
        _NLPS[nkey] = AssembledNLP(wd, K, threads=threads)
    nlp = _NLPS[nkey]
    skey = (nkey, tuple(sorted(ipopt_opts.items())))
    if skey not in _SOLVERS:
        _SOLVERS[skey] = nlp.solver(ipopt_opts)
    return nlp, _SOLVERS[skey]


def homotopy_stages(opt) -> list:
    """[(exponent, hard, penalty, homotopy)] solved in sequence, each warm-started."""
    if opt.collision_homotopy:
        return [(2.0, False, opt.collision_penalty, True), (6.0, opt.collision_hard_constraint, opt.collision_penalty, True)]
    return [(2.0, opt.collision_hard_constraint, opt.collision_penalty, False)]


def solve(prob: Problem, model: G1Model | None = None, threads: int = 2) -> TOResult:
    """Solve the TO.  Raises ProblemError on invalid input (before any solve)."""
    model = model or default_model()
    t_start = time.perf_counter()
    validate_problem(prob, model)
    opt = prob.options
    data = ProblemData(prob, model)
    win, wd = get_window(model, data.structure)
    K = data.grid.K
    ipopt_opts = {
        "max_iter": int(opt.max_iterations), "tol": float(opt.tol), "constr_viol_tol": float(opt.constr_tol),
        "acceptable_tol": 1e-2, "acceptable_constr_viol_tol": 1e-3, "acceptable_iter": 10,
        "print_level": int(opt.print_level), "linear_solver": "mumps", "mu_strategy": "adaptive",
        "max_wall_time": float(opt.time_limit), "bound_push": 1e-6, "bound_frac": 1e-6,
        "nlp_scaling_max_gradient": 100.0, "sb": "yes",
    }
    ipopt_opts.update(opt.ipopt or {})
    nlp, solver = get_solver(wd, data.structure, K, ipopt_opts, threads)
    build_time = time.perf_counter() - t_start
    stages_out = []
    z0 = lam_x = lam_g = None
    sol = None
    solve_time = 0.0
    iters = 0
    status = ""
    warm = dict(ipopt_opts)
    warm.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-6,
                 "warm_start_mult_bound_push": 1e-6, "mu_init": 1e-4})
    for si, (expo, hard, pen, hom) in enumerate(homotopy_stages(opt)):
        lbw, ubw, lbg, ubg, Pm, W0 = data.fill(win, expo, hard, pen, hom)
        args = dict(lbx=_vec(lbw), ubx=_vec(ubw), lbg=_vec(lbg), ubg=_vec(ubg), p=_vec(Pm))
        last_stage = si == len(homotopy_stages(opt)) - 1
        if z0 is None:
            args["x0"] = _vec(W0)
            s = solver
            if not last_stage:  # the surrogate stage only guides: cap its iterations
                s = _stage_solver(nlp, data.structure, K, ipopt_opts, "guide")
        else:
            args["x0"] = np.clip(z0, args["lbx"], args["ubx"])
            args["lam_x0"] = lam_x
            args["lam_g0"] = lam_g
            if "warm" not in _SOLVERS.get(("warm", data.structure, K), {}):
                _SOLVERS[("warm", data.structure, K)] = {"warm": nlp.solver(warm)}
            s = _SOLVERS[("warm", data.structure, K)]["warm"]
        t0 = time.perf_counter()
        sol = s(**args)
        dt = time.perf_counter() - t0
        st = s.stats()
        solve_time += dt
        iters += int(st.get("iter_count", 0))
        status = st.get("return_status", "")
        stages_out.append({"exponent": expo, "hard": hard, "status": status, "iterations": int(st.get("iter_count", 0)),
                           "time": dt})
        z0 = np.array(sol["x"]).ravel()
        lam_x = np.array(sol["lam_x"]).ravel()
        lam_g = np.array(sol["lam_g"]).ravel()
        if time.perf_counter() - t_start > opt.time_limit:
            status = status + " (time limit)"
            break
    converged = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    res = extract(model, data, win, nlp, z0, args, Pm, lbg, ubg)
    stats = res.stats
    stats.converged = converged
    stats.status = status
    stats.iterations = iters
    stats.build_time = build_time
    stats.solve_time = solve_time
    stats.cost = float(sol["f"])
    stats.stages = stages_out
    stats.peak_memory_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    stats.checks = run_checks(model, data, res)
    tol_ok = stats.max_constraint_violation.value <= 1e-2
    stats.success = bool(converged and tol_ok and all(c["ok"] for c in stats.checks.values()))
    res.densify(opt.output_rate)
    res.data = data
    return res


def _stage_solver(nlp, structure, K, ipopt_opts, tag):
    key = (tag, structure, K, tuple(sorted(ipopt_opts.items())))
    if key not in _SOLVERS:
        o = dict(ipopt_opts)
        o["max_iter"] = min(int(o["max_iter"]), GUIDE_STAGE_MAX_ITER)
        o["acceptable_iter"] = 3
        _SOLVERS[key] = nlp.solver(o)
    return _SOLVERS[key]


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
    is_col = lambda nm: ("collision" in nm or "surrogate" in nm or nm.startswith("self"))
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
                    ci = tree["p"][jid] + tree["R"][jid] @ SOLE_CORNERS[i]
                    T[k] += np.cross(ci - pt, u[i])
            else:
                F[k] = Wm[W[f"u_{limb}"], k] * mg
                if c is not None:
                    n = Pm[win.P[f"{limb}_n"], k]
                    sel = Pm[win.P[f"{limb}_sel"], k]
                    Rs = sel[0] * np.eye(3)
                    for j in range(len(data.moving)):
                        Rs = Rs + sel[j + 1] * rpy_to_rot(Wm[W[f"o{j}_pose"], k][3:])
                    Nn[k] = Rs @ n
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
