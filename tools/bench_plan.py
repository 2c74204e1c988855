#!/usr/bin/env python3
"""Benchmark of the plan pipeline from prompts (issue 5): perception -> retargeting -> schedule -> TO.

For every task (ros_ws/config/tasks/*.yaml) and every point of its scenario's grid
(src/lomanip_sim/config/scenarios.yaml) it runs the ROS-free pipeline (lomanip_planner.offline) and
prints, per case: stage times, the retargeted keyframes' worst contact residual, joint limits,
smallest self-collision distance, worst stance-foot tilt and IK time per keyframe. With --solve it
also runs the TO twice (the paper's Sec. V-C ablation) with the task file's TO options (what the
plan service gets): AllKeyframe (base cost, foot cost, warm start) and NoKeyframe (all three off),
and prints convergence, physical success, iterations, time. Each TO result is saved under
<out>/to/ for tools/bench_exec.py --bench-to <out>/to.

    .venv/bin/python tools/bench_plan.py                      # retargeting over both grids (~3 min)
    .venv/bin/python tools/bench_plan.py --solve --cases 1    # + TO on the first grid point of each task
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]


def load_task(name: str) -> dict:
    return yaml.safe_load((ROOT / "ros_ws/config/tasks" / f"{name}.yaml").read_text())


def grid(scenario: str, base: dict) -> list[dict]:
    from lomanip_sim.scenario import load_grid

    keys = yaml.safe_load((ROOT / "src/lomanip_sim/config/scenarios.yaml").read_text())["scenarios"][scenario]["grid"]
    out = []
    for params in load_grid(scenario):
        d = params.to_dict()
        out.append({**base, **{k: d[k] for k in keys}})
    return out


def variant_options(task: dict, variant: str, max_iterations: int | None):
    """The task file's TO options (what the plan service gets) with the variant's keyframe switches."""
    from lomanip_to.fixtures import load_options

    on = variant == "AllKeyframe"
    opt = load_options(task.get("options")).replaced(
        use_keyframe_base_cost=on, use_keyframe_foot_cost=on, use_keyframe_warm_start=on)
    return opt if max_iterations is None else opt.replaced(max_iterations=max_iterations)


def placement_goals(task: dict) -> dict:
    """The task file's placement goals, by object (what the plan service gets)."""
    from lomanip_to.problem import PlacementGoal

    return {g["object"]: PlacementGoal(g["object"], tuple(g["position"]), float(g.get("yaw", 0.0)))
            for g in task.get("placement_goals", [])}


def run_case(task: dict, overrides: dict, solve: bool, variants: list[str], max_iterations: int | None,
             out: Path | None = None, task_name: str = "") -> dict:
    from dataclasses import replace

    from bench_to import progress_printer   # tools/ is on sys.path when run as a script
    from lomanip_planner import offline
    from lomanip_to import solver

    row: dict = {"scenario": task["scenario"], "overrides": overrides}
    try:
        plan = offline.plan(task["scenario"], task["prompts"], placement_goals(task), overrides, solve=False)
    except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    row["timings"] = dict(plan.timings)
    row["keyframes"] = []
    for kf in plan.keyframes:
        r, lb = kf.retarget, kf.load_balance
        row["keyframes"].append({
            "max_residual_m": max(r.residuals.values()), "within_limits": r.within_joint_limits,
            "min_self_distance_m": r.min_self_distance, "max_foot_tilt_rad": max(r.foot_tilt.values()),
            "ik_s": r.seconds,
            # the robot-and-load CoM inside the soles (m) of a keyframe whose hands hold a weight
            "load_margin_m": None if lb is None else [lb.margin_before, lb.margin_after],
            "feet_step_m": None if lb is None else float(np.linalg.norm(lb.shift))})
    row["duration_s"] = plan.problem.duration
    row["phases"] = len(plan.problem.phases)
    if solve:
        row["to"] = {}
        for v in variants:
            prob = replace(plan.problem, options=variant_options(task, v, max_iterations))
            t0 = time.perf_counter()
            res = solver.solve(prob, progress=progress_printer(f"    {task['scenario']} {v}"))
            s = res.stats
            if out is not None:  # tools/bench_exec.py --bench-to <out>/to executes it
                name = f"{task['scenario']}_prompts_" + "_".join(f"{k}{overrides[k]:g}" for k in sorted(overrides)
                                                                if isinstance(overrides[k], (int, float)))
                out.mkdir(parents=True, exist_ok=True)
                res.save(out / f"{name}_{v}.npz")
                saved = json.loads((out / "summary.json").read_text()) if (out / "summary.json").is_file() else {"rows": []}
                saved["rows"] = [r for r in saved["rows"] if (r["case"], r["variant"]) != (name, v)]
                # the task lets tools/bench_exec.py rebuild the plan's contact schedule
                saved["rows"].append({"case": name, "variant": v, "overrides": overrides, "task": task_name})
                (out / "summary.json").write_text(json.dumps(saved, indent=1))
            row["to"][v] = {"converged": s.converged, "success": bool(res.success), "iterations": s.iterations,
                            "wall_s": time.perf_counter() - t0, "peak_mb": s.peak_memory_mb,
                            "status": s.status_message()}
            print(f"    TO {v}: {s.status_message()} ({time.perf_counter() - t0:.0f} s)", flush=True)
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tasks", nargs="+", default=["s1_basket", "s2_trolley"])
    ap.add_argument("--cases", type=int, default=0, help="first N grid points per task (0 = all)")
    ap.add_argument("--solve", action="store_true", help="also run the TO (minutes per case)")
    ap.add_argument("--variants", nargs="+", default=["AllKeyframe", "NoKeyframe"])
    ap.add_argument("--max-iterations", type=int, default=None,
                    help="ipopt's cap per stage (default: the task file's, else the TO's default)")
    ap.add_argument("--out", type=Path, default=ROOT / "runs/bench_plan")
    args = ap.parse_args()

    rows = []
    for name in args.tasks:
        task = load_task(name)
        cases = grid(task["scenario"], dict(task.get("scenario_overrides") or {}))
        cases = cases[: args.cases] if args.cases else cases
        for ov in cases:
            print(f"{name} {ov}", flush=True)
            row = run_case(task, ov, args.solve, args.variants, args.max_iterations, args.out / "to", name)
            row["task"] = name
            rows.append(row)
            if "error" in row:
                print(f"    FAILED: {row['error']}", flush=True)
            else:
                kf = row["keyframes"]
                print(f"    perception {row['timings']['perception']:.1f} s, retargeting "
                      f"{row['timings']['retargeting']:.1f} s; worst residual "
                      f"{max(k['max_residual_m'] for k in kf) * 100:.2f} cm, limits "
                      f"{all(k['within_limits'] for k in kf)}, min self distance "
                      f"{min(k['min_self_distance_m'] for k in kf) * 1000:.0f} mm, worst foot tilt "
                      f"{max(k['max_foot_tilt_rad'] for k in kf):.3f} rad; horizon {row['duration_s']:.1f} s, "
                      f"{row['phases']} phases", flush=True)

    ok = [r for r in rows if "error" not in r]
    kfs = [k for r in ok for k in r["keyframes"]]
    print("\nsummary")
    print(f"  cases: {len(rows)}, retargeted: {len(ok)}, failed: {len(rows) - len(ok)}")
    if kfs:
        print(f"  keyframes: {len(kfs)}; worst contact residual {max(k['max_residual_m'] for k in kfs) * 100:.2f} cm; "
              f"joint limits held in {sum(k['within_limits'] for k in kfs)}/{len(kfs)}; self-collision-free in "
              f"{sum(k['min_self_distance_m'] >= 0 for k in kfs)}/{len(kfs)}; worst foot tilt "
              f"{max(k['max_foot_tilt_rad'] for k in kfs):.3f} rad")
        loads = [k for k in kfs if k["load_margin_m"] is not None]
        if loads:
            from lomanip_planner.keyframes import LOAD_BALANCE_MARGIN

            need = LOAD_BALANCE_MARGIN or 0.0
            after = [k["load_margin_m"][1] for k in loads]
            print(f"  keyframes holding a weight: {len(loads)}; robot-and-load CoM inside the soles: worst "
                  f"{min(k['load_margin_m'][0] for k in loads) * 100:+.1f} cm before, {min(after) * 100:+.1f} cm after "
                  f"(>= {need * 100:.0f} cm in {sum(a >= need - 1e-3 for a in after)}); feet stepped in "
                  f"{sum(k['feet_step_m'] > 1e-3 for k in loads)}, at most {max(k['feet_step_m'] for k in loads) * 100:.1f} cm")
        print(f"  IK time per keyframe: median {statistics.median(k['ik_s'] for k in kfs):.2f} s, "
              f"max {max(k['ik_s'] for k in kfs):.2f} s")
        print(f"  perception per case: median {statistics.median(r['timings']['perception'] for r in ok):.1f} s")
    if args.solve:
        for v in args.variants:
            res = [r["to"][v] for r in ok if "to" in r]
            print(f"  TO {v}: converged {sum(t['converged'] for t in res)}/{len(res)}, "
                  f"physically consistent {sum(t['success'] for t in res)}/{len(res)}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps(rows, indent=1, default=str))
    print(f"  details: {args.out / 'summary.json'}")
    return 0 if len(ok) == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
