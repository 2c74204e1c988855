#!/usr/bin/env python3
"""Whole-body TO benchmark on the paper's S1/S2 grid (issue 3; paper Sec. V-A and the V-C ablation).

For every grid cell (box mass x box yaw, from the ``grid`` of lomanip_sim's scenarios.yaml) and
every variant it builds the fixture problem (src/lomanip_to/config/s1_basket.yaml,
s2_trolley.yaml), solves it and records: converged ("optimal" when ipopt's test is met, "stalled" when the stall
acceptance stopped a feasible final stage, see solver.STALLED_STATUS), success (converged AND the physical checks),
iterations, build / solve wall time, peak resident memory of this process, max constraint
violation, max penetration, and how deep a forearm reaches into the object its hand holds
("forearm mm": reported, not a check; docs/to.md, session 40).  Variants (``Options`` switches):

  all        AllKeyframe: keyframe base cost eq. (1), foot cost eq. (2), keyframe warm start
  none       NoKeyframe: all three keyframe components off
  no_base / no_foot / no_warm   one component removed (``--variants`` to select them)

Each result is saved as runs/bench_to/<case>_<variant>.npz (``lomanip_to.result.TOResult.load``
reads it back; the execution benchmark uses these files) and the table as
runs/bench_to/summary.json.  The penetration over time of each result (sum of the robot's
penetration depths into objects and environment per knot, the paper's Fig. 3 quantity) is plotted
to runs/bench_to/<case>_<variant>_penetration.png, and the variants of one case are overlaid in
runs/bench_to/<case>_penetration.png.  Peak memory is the process maximum so far (ru_maxrss), so it only
grows along the run.  Timings are on this machine (2 shared cores; expect them higher under load).

  .venv/bin/python tools/bench_to.py                  # nominal S1 and S2, AllKeyframe + NoKeyframe
  .venv/bin/python tools/bench_to.py --full           # the whole grid (hours)
  .venv/bin/python tools/bench_to.py --scenarios s1_basket --variants all
  .venv/bin/python tools/bench_to.py --scenarios s2_trolley --variants all --cell box_mass=5.0,box_yaw=0.6
"""
from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
for pkg in ("src/lomanip_to", "src/lomanip_sim"):
    sys.path.insert(0, str(ROOT / pkg))

from lomanip_sim.scenario import default_scenarios_path  # noqa: E402
from lomanip_to import solver  # noqa: E402
from lomanip_to.fixtures import load_problem  # noqa: E402
from lomanip_to.model import G1Model  # noqa: E402
from lomanip_to.problem import ProblemError  # noqa: E402

VARIANTS = {
    "all": {},
    "none": {"use_keyframe_base_cost": False, "use_keyframe_foot_cost": False, "use_keyframe_warm_start": False},
    "no_base": {"use_keyframe_base_cost": False},
    "no_foot": {"use_keyframe_foot_cost": False},
    "no_warm": {"use_keyframe_warm_start": False},
}
SCENARIOS = ("s1_basket", "s2_trolley")
COLUMNS = ("case", "variant", "converged", "success", "iterations", "build_s", "solve_s", "peak_mb",
           "max_violation", "penetration_mm", "held_forearm_mm")


def grid(scenario: str) -> list[dict]:
    """The paper's grid of ``scenario`` as override dicts (cartesian product, YAML order)."""
    with open(default_scenarios_path()) as fh:
        g = yaml.safe_load(fh)["scenarios"][scenario].get("grid") or {}
    keys = list(g)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(g[k] for k in keys))]


def progress_printer(label: str):
    """TO progress hook printing a line per stage and every 50 iterations, so a long solve shows where it is."""
    last = {"stage": None}

    def report(pr):
        if pr.stage != last["stage"] or pr.iteration % 50 == 0:
            last["stage"] = pr.stage
            print(f"{label}: {pr.stage or 'solve'} iteration {pr.iteration}, violation "
                  f"{pr.constraint_violation:.1e}, {pr.elapsed:.0f} s", flush=True)
    return report


def case_name(scenario: str, over: dict) -> str:
    return scenario + "".join(f"_{k.replace('box_', '')}{v:g}" for k, v in over.items())


def plot_penetration(path: Path, title: str, curves: list) -> None:
    """One PNG: penetration (mm) over time for each (label, t, penetration_m) curve, with the
    5 mm acceptance line.  Agg backend: no display needed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 2.6), dpi=110)
    for label, t, pen in curves:
        ax.plot(t, 1e3 * np.asarray(pen), label=label, lw=1.4)
    ax.axhline(5.0, color="k", ls="--", lw=0.8, label="5 mm limit")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("penetration (mm)")
    ax.set_title(title, fontsize=9)
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def run_case(model, scenario: str, over: dict, variant: str, out: Path, time_limit: float | None,
             extra: dict | None = None, resolve: bool = False) -> dict:
    opts = dict(VARIANTS[variant], **(extra or {}))
    if time_limit is not None:
        opts["time_limit"] = time_limit
    name = case_name(scenario, over)
    t0 = time.perf_counter()
    prob = load_problem(scenario, overrides=over, model=model, options=opts)
    load_s = time.perf_counter() - t0
    res = solver.solve(prob, model, progress=progress_printer(f"  {name} {variant}"))
    s = res.stats
    res.save(out / f"{name}_{variant}.npz")
    plot_penetration(out / f"{name}_{variant}_penetration.png",
                     f"{name} {variant}: {'success' if res.success else 'FAILED'}, max {1e3 * s.max_penetration:.1f} mm",
                     [(variant, res.t_knots, res.penetration_knots)])
    resolve_s = None
    if resolve:  # the same problem again in this process: window Functions, NLPs and solvers cached
        t1 = time.perf_counter()
        solver.solve(load_problem(scenario, overrides=over, model=model, options=opts), model)
        resolve_s = time.perf_counter() - t1
    return {"case": name, "variant": variant, "overrides": over, "converged": s.converged,
            "resolve_s": resolve_s,
            "convergence": convergence_kind(s.converged, s.status), "success": res.success,
            "iterations": s.iterations, "build_s": load_s + s.build_time, "solve_s": s.solve_time,
            "peak_mb": s.peak_memory_mb, "max_violation": s.max_constraint_violation.value,
            "max_violation_where": s.max_constraint_violation.text(), "penetration_mm": 1e3 * s.max_penetration,
            "status": s.status_message(), "stages": s.stages, "n_knots": s.n_knots,
            "held_forearm_mm": _held_forearm_mm(s.checks),
            "checks": {k: bool(c["ok"]) for k, c in s.checks.items()}}


def _held_forearm_mm(checks: dict) -> float | None:
    """How deep (mm) a forearm sphere reaches into the object its hand holds (reported, not gated;
    lomanip_to.checks.held_object_forearm_depth), or None without the checks."""
    v = (checks or {}).get("penetration", {}).get("held_object_forearm")
    return None if v is None else 1e3 * float(v)


def convergence_kind(converged: bool, status: str) -> str:
    """'optimal' (ipopt's tolerance or acceptable test), 'stalled' (the stall acceptance:
    feasible, objective flat; solver.STALLED_STATUS), 'capped' (a feasible iterate at the
    iteration cap; solver.CAPPED_FEASIBLE_STATUS), 'early-stop' (a feasible iterate before ipopt
    stopped by itself; solver.FEASIBLE_BEFORE_STOP_STATUS) or 'no'."""
    if not converged:
        return "no"
    if solver.CAPPED_FEASIBLE_STATUS in status:
        return "capped"
    if solver.FEASIBLE_BEFORE_STOP_STATUS in status:
        return "early-stop"
    return "stalled" if solver.STALLED_STATUS in status else "optimal"


def _load_penetration(path: Path) -> tuple:
    with np.load(path, allow_pickle=False) as z:
        return z["a/t_knots"], z["a/penetration_knots"]


def fmt_row(r: dict) -> str:
    return (f"{r['case']:<24} {r['variant']:<8} {r.get('convergence', str(r['converged'])):<9} {str(r['success']):<7} "
            f"{r['iterations']:>5d} {r['build_s']:>7.1f} {r['solve_s']:>7.1f} {r['peak_mb']:>7.0f} "
            f"{r['max_violation']:>9.1e} {r['penetration_mm']:>6.1f} "
            f"{'-' if r.get('held_forearm_mm') is None else format(r['held_forearm_mm'], '.1f'):>10}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="the whole grid (default: nominal cells only)")
    ap.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=SCENARIOS)
    ap.add_argument("--variants", nargs="+", default=["all", "none"], choices=list(VARIANTS))
    ap.add_argument("--time-limit", type=float, default=None, help="per solve (s); default: Options")
    ap.add_argument("--option", action="append", default=[], metavar="KEY=YAML",
                    help="an Options field for every solve, e.g. --option guide_hessian=cost (repeatable)")
    ap.add_argument("--cell", action="append", default=[], metavar="KEY=VALUE[,KEY=VALUE]",
                    help="only the grid cells that match (repeatable), e.g. --cell box_mass=5.0,box_yaw=0.6")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=NUMBER", dest="params",
                    help="a fixture parameter for every cell (repeatable), e.g. --set grip_z=0.0")
    ap.add_argument("--resolve", action="store_true",
                    help="solve each case a second time in the same process (cached build) and report it")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "bench_to")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    extra = {}
    for item in a.option:
        key, _, value = item.partition("=")
        extra[key] = yaml.safe_load(value)
    model = G1Model()
    rows = []
    header = (f"{'case':<24} {'variant':<8} {'converged':<9} {'success':<7} {'iter':>5} {'build s':>7} "
              f"{'solve s':>7} {'peak MB':>7} {'max viol':>9} {'pen mm':>6} {'forearm mm':>10}")
    print(header, flush=True)
    try:
        wanted = [{k: float(v) for k, _, v in (kv.partition("=") for kv in spec.split(","))} for spec in a.cell]
    except ValueError:
        print(f"bench_to: --cell wants KEY=NUMBER[,KEY=NUMBER], got {a.cell}", file=sys.stderr)
        return 2
    try:
        params = {k: float(v) for k, _, v in (item.partition("=") for item in a.params)}
    except ValueError:
        print(f"bench_to: --set wants KEY=NUMBER, got {a.params}", file=sys.stderr)
        return 2
    for sc in a.scenarios:
        cells = grid(sc) if a.full or wanted else grid(sc)[:1]
        if wanted:
            cells = [c for c in cells if any(all(k in c and abs(float(c[k]) - v) < 1e-9 for k, v in w.items())
                                             for w in wanted)]
        for cell, variant in itertools.product(cells, a.variants):
            over = {**cell, **params}
            try:
                r = run_case(model, sc, over, variant, a.out, a.time_limit, extra, a.resolve)
            except ProblemError as exc:  # a bad --option (or problem) is refused before any solve
                print(f"bench_to: {exc}", file=sys.stderr)
                return 2
            rows.append(r)
            print(fmt_row(r), flush=True)
            if r["resolve_s"] is not None:
                print(f"{'':<24} cached re-solve {r['resolve_s']:.1f} s (load + build + solve)", flush=True)
            (a.out / "summary.json").write_text(json.dumps({"rows": rows, "columns": COLUMNS}, indent=1))
            case_rows = [q for q in rows if q["case"] == r["case"]]
            if len(case_rows) > 1:  # variants of one case overlaid (paper Fig. 3 style)
                plot_penetration(a.out / f"{r['case']}_penetration.png", r["case"], [
                    (q["variant"], *_load_penetration(a.out / f"{q['case']}_{q['variant']}.npz")) for q in case_rows])
    print(f"\n{sum(r['success'] for r in rows)}/{len(rows)} succeeded; results under {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
