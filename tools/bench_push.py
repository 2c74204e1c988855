#!/usr/bin/env python3
"""Benchmark of the demo's push (issue 6): plan it from its prompt, execute it under physics.

Each case is the `make demo` task (ros_ws/config/tasks/push_trolley.yaml) with the trolley moved a
little: the offline pipeline (perception -> retargeting -> schedule -> TO, lomanip_planner.offline)
plans it with the task's TO options, and the whole-body controller executes the plan in the
scenario's MuJoCo world (torques only, lomanip_sim.execution). Why: whether a push plan executes has
changed with small changes of the problem (docs/execution.md), so one plan says little; this
counts over several. Prints per case: TO status, iterations and time, fell (and when), trolley
distance, max/RMS pelvis error; writes runs/bench_push/summary.json.

    .venv/bin/python tools/bench_push.py                 # 4 cases, about 4 min each on 2 cores
    .venv/bin/python tools/bench_push.py --cases base --set double_support_com_margin=null
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
for _p in ("src/lomanip_to", "src/lomanip_sim", "src/lomanip_planner", "src/lomanip_perception"):
    sys.path.insert(0, str(ROOT / _p))
os.environ.setdefault("MUJOCO_GL", "egl")

TASK = ROOT / "ros_ws/config/tasks/push_trolley.yaml"
#: trolley chassis centre (m) per case; "base" is the demo's own layout
CASES = {"base": None, "near": [0.80, 0.0], "far_left": [0.90, 0.05], "right": [0.85, -0.05]}


def run_case(name: str, position, extra_options: dict, out_root: Path) -> dict:
    from lomanip_planner import offline
    from lomanip_sim.execution import Execution
    from lomanip_sim.media import save_run
    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.simulator import Simulation
    from lomanip_sim.trajectory import from_to_result
    from lomanip_to import fixtures

    task = yaml.safe_load(TASK.read_text())
    overrides = dict(task.get("scenario_overrides") or {})
    if position is not None:
        overrides["trolley_position"] = position
    solver_yaml = yaml.safe_load(Path(fixtures.CONFIG_DIR, "solver.yaml").read_text())
    options = fixtures.load_options(solver_yaml.get("options"))
    options = fixtures.load_options(task.get("options"), options)
    options = fixtures.load_options(extra_options, options)
    t0 = time.perf_counter()
    plan = offline.plan(task["scenario"], task["prompts"], overrides=overrides, options=options)
    res = plan.result
    row = {"case": name, "trolley_position": overrides.get("trolley_position"), "to_status": res.stats.status,
           "to_success": bool(res.success), "to_iterations": res.stats.iterations,
           "plan_time_s": round(time.perf_counter() - t0, 1)}
    (out_root / name).mkdir(parents=True, exist_ok=True)
    res.save(out_root / name / "plan.npz")  # TOResult.load reads it back (tools/bench_exec.py style)
    if not res.success:
        return row
    res.densify()
    traj = from_to_result(res, plan.problem.phases, scenario=task["scenario"])
    ex = Execution(Simulation(load_scenario(task["scenario"], overrides)), traj)
    m = ex.run()
    save_run(out_root / name, ex, name, video=False)
    row.update(m.as_dict())
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    ap.add_argument("--set", action="append", default=[], metavar="OPTION=YAML",
                    help="override a TO option of the task, e.g. max_cmp_offset=0 (repeatable)")
    ap.add_argument("--out", default="runs/bench_push")
    args = ap.parse_args()
    extra = {}
    for item in args.set:
        key, sep, val = item.partition("=")
        if not sep:
            print(f"bench_push: --set expects OPTION=VALUE, got {item!r}", file=sys.stderr)
            return 2
        extra[key] = yaml.safe_load(val)
    out_root = ROOT / args.out
    out_root.mkdir(parents=True, exist_ok=True)
    print(f"{'case':<10}{'TO':>22}{'it':>6}{'plan s':>8}{'fell':>6}{'end s':>7}{'trolley':>9}"
          f"{'pelvis max/rms cm':>19}{'success':>9}")
    rows = []
    for name in args.cases:
        row = run_case(name, CASES[name], extra, out_root)
        rows.append(row)
        if "fell" not in row:
            print(f"{name:<10}{row['to_status'][:21]:>22}{row['to_iterations']:>6}{row['plan_time_s']:>8.0f}  not executed")
            continue
        trolley = row["task_success_detail"].split("trolley moved ")[-1].split(" m")[0]
        print(f"{name:<10}{row['to_status'][:21]:>22}{row['to_iterations']:>6}{row['plan_time_s']:>8.0f}"
              f"{str(row['fell']):>6}{row['duration']:>7.2f}{trolley:>9}"
              f"{100 * row['max_base_position_error']:>10.1f}/{100 * row['rms_base_position_error']:<8.1f}"
              f"{str(row['task_success']):>9}")
    done = [r for r in rows if "fell" in r]
    print(f"executed without a fall {sum(not r['fell'] for r in done)}/{len(rows)}; task success "
          f"{sum(bool(r.get('task_success')) for r in done)}/{len(rows)}; outputs under {out_root}")
    (out_root / "summary.json").write_text(json.dumps({"options": extra, "rows": rows}, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
