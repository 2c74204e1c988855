#!/usr/bin/env python3
"""Benchmark of the whole-body TO on the S1/S2 fixtures (paper Sec. V grids and keyframe ablation).

Prints a table (converged, iterations, build/solve wall time, peak memory, max penetration, max
constraint violation with where) and writes ``runs/bench_to/<stamp>/results.json`` plus one
penetration-over-time plot per scenario.  Each cell runs in its own subprocess so peak memory
(``ru_maxrss``) is per cell and a crash or time-out cannot take the table down.

Examples::

    python src/lomanip_to/scripts/bench_to.py --scenario s1 --quick        # nominal cell only
    python src/lomanip_to/scripts/bench_to.py --scenario s1 s2             # full mass x yaw grids
    python src/lomanip_to/scripts/bench_to.py --scenario s1 --ablation     # keyframe ablation
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "lomanip_to"))
sys.path.insert(0, os.path.join(ROOT, "src", "lomanip_sim"))

GRIDS = {
    "s1": ("s1_basket", [2.5, 5.0], [0.0, 0.6, 1.2]),
    "s2": ("s2_trolley", [2.5, 5.0, 7.5], [0.0, 0.6, -0.6, 1.2, -1.2]),
}
ABLATIONS = {
    "AllKeyframe": {},
    "NoKeyframe": {"use_keyframe_base_cost": False, "use_keyframe_foot_cost": False,
                   "use_keyframe_warm_start": False},
    "NoBaseCost": {"use_keyframe_base_cost": False},
    "NoFootCost": {"use_keyframe_foot_cost": False},
    "NoWarmStart": {"use_keyframe_warm_start": False},
}


def run_cell(fixture: str, mass: float, yaw: float, options: dict, timeout: float) -> dict:
    """Solve one cell in a subprocess; returns the summary dict."""
    code = f"""
import json, sys, time
sys.path.insert(0, {os.path.join(ROOT, 'src', 'lomanip_to')!r}); sys.path.insert(0, {os.path.join(ROOT, 'src', 'lomanip_sim')!r})
t0 = time.perf_counter()
from lomanip_to.fixtures import load_problem
from lomanip_to.model import G1Model
from lomanip_to import solver
m = G1Model()
p = load_problem({fixture!r}, overrides={{'box_mass': {mass}, 'box_yaw': {yaw}}}, options={options!r}, model=m)
r = solver.solve(p, m)
s = r.stats
out = dict(converged=s.converged, success=r.success, status=s.status, iterations=s.iterations,
           build_time=s.build_time, solve_time=s.solve_time, wall=time.perf_counter() - t0,
           peak_memory_mb=s.peak_memory_mb, max_penetration=s.max_penetration,
           max_violation=s.max_constraint_violation.value, violation_where=s.max_constraint_violation.text(),
           dynamics=s.max_dynamics_violation.text(), contact=s.max_contact_violation.text(),
           checks={{k: {{'value': v['value'], 'ok': bool(v['ok']), 'where': v['where']}} for k, v in s.checks.items()}},
           knots=s.n_knots, n_variables=s.n_variables, stages=s.stages,
           t=r.t_knots.tolist(), penetration=r.penetration_knots.tolist())
print('@@RESULT@@' + json.dumps(out))
"""
    t0 = time.perf_counter()
    try:
        cp = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"converged": False, "success": False, "status": f"timeout after {timeout:.0f} s",
                "wall": time.perf_counter() - t0}
    for line in cp.stdout.splitlines():
        if line.startswith("@@RESULT@@"):
            return json.loads(line[len("@@RESULT@@"):])
    return {"converged": False, "success": False, "status": "crashed: " + cp.stderr.strip()[-300:],
            "wall": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", nargs="+", default=["s1", "s2"], choices=sorted(GRIDS))
    ap.add_argument("--quick", action="store_true", help="nominal cell only (first mass, yaw 0)")
    ap.add_argument("--ablation", action="store_true", help="keyframe ablation on the nominal cell")
    ap.add_argument("--timeout", type=float, default=600.0, help="per-cell wall-clock limit (s)")
    ap.add_argument("--out", default=os.path.join(ROOT, "runs", "bench_to"))
    args = ap.parse_args(argv)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    out_dir = os.path.join(args.out, stamp)
    os.makedirs(out_dir, exist_ok=True)
    rows = []
    from lomanip_to.fixtures import config_path

    for sc in args.scenario:
        fixture, masses, yaws = GRIDS[sc]
        if not os.path.isfile(config_path(fixture)):
            print(f"{sc}: fixture {fixture}.yaml not written yet - skipped")
            continue
        cells = []
        if args.ablation:
            cells = [(masses[0], 0.0, name, opts) for name, opts in ABLATIONS.items()]
        elif args.quick:
            cells = [(masses[0], 0.0, "AllKeyframe", {})]
        else:
            cells = [(m, y, "AllKeyframe", {}) for m in masses for y in yaws]
        for (mass, yaw, abl, opts) in cells:
            r = run_cell(fixture, mass, yaw, opts, args.timeout)
            r.update(scenario=sc, mass=mass, yaw=yaw, ablation=abl)
            rows.append(r)
            print(_row(r), flush=True)
    with open(os.path.join(out_dir, "results.json"), "w") as f:
        json.dump(rows, f, indent=1)
    _plots(rows, out_dir)
    print("\n" + _table(rows))
    print(f"\nwritten: {out_dir}/results.json and penetration plots")
    return 0


HEADER = (f"{'scen':4} {'abl':12} {'mass':>4} {'yaw':>5} {'conv':>4} {'ok':>3} {'iter':>4} {'build':>6} "
          f"{'solve':>7} {'mem MB':>7} {'pen mm':>7} {'viol':>8}  where")


def _row(r):
    return (f"{r['scenario']:4} {r['ablation']:12} {r['mass']:4.1f} {r['yaw']:5.2f} "
            f"{'yes' if r.get('converged') else 'no':>4} {'yes' if r.get('success') else 'no':>3} "
            f"{r.get('iterations', 0):4d} {r.get('build_time', float('nan')):6.1f} "
            f"{r.get('solve_time', float('nan')):7.1f} {r.get('peak_memory_mb', float('nan')):7.0f} "
            f"{1e3 * r.get('max_penetration', float('nan')):7.1f} {r.get('max_violation', float('nan')):8.1e}  "
            f"{r.get('violation_where', r.get('status', ''))}")


def _table(rows):
    return "\n".join([HEADER] + [_row(r) for r in rows])


def _plots(rows, out_dir):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except Exception:  # noqa: BLE001
        return
    for sc in sorted({r["scenario"] for r in rows}):
        fig, ax = plt.subplots(figsize=(7, 3.5))
        for r in rows:
            if r["scenario"] != sc or "t" not in r:
                continue
            ax.plot(r["t"], [-1e3 * p for p in r["penetration"]],
                    label=f"{r['ablation']} {r['mass']} kg {r['yaw']} rad")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("sum of negative signed distances (mm)")
        ax.set_title(f"{sc}: collision penetration over time")
        ax.legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(os.path.join(out_dir, f"penetration_{sc}.png"), dpi=120)
        plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
