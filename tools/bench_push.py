#!/usr/bin/env python3
"""Benchmark of the demo's push (issue 6): plan it from its prompt, execute it under physics.

Each case is the `make demo` task (ros_ws/config/tasks/push_trolley.yaml) with the trolley moved a
little: the offline pipeline (perception -> retargeting -> schedule -> TO, lomanip_planner.offline)
plans it with the task's TO options, and the whole-body controller executes the plan in the
scenario's MuJoCo world (torques only, lomanip_sim.execution). Why: whether a push plan executes has
changed with small changes of the problem (docs/execution.md), so one plan says little; this
counts over several. Prints per case: TO status, iterations and time, fell (and when), trolley
distance, max/RMS pelvis error; writes runs/bench_push/summary.json (summary_replay.json with --replay).

    .venv/bin/python tools/bench_push.py                 # 4 cases, about 4 min each on 2 cores
    .venv/bin/python tools/bench_push.py --cases all     # 8 layouts
    .venv/bin/python tools/bench_push.py --cases base --set double_support_com_margin=null
    .venv/bin/python tools/bench_push.py --replay        # execute the saved plans again, no TO
    .venv/bin/python tools/bench_push.py --replay --cases base --video   # + MP4, frames, strip
    .venv/bin/python tools/bench_push.py --problems runs/*/logs/to_problem_1.pkl --out runs/bench_push_graph

``--problems`` re-solves TO problems that graph runs saved (the TO node's ``problem_dir``; each
``lomanip plan``/``make demo`` run keeps its own under ``runs/<run>/logs/``) with the task's current
TO options, then executes them from the scenario's start: the graph's own problems, whose plans
fall more often than the layouts' (docs/execution.md, session 14). Cases are named after the run
folder; ``--replay --problems ...`` executes their saved plans again, ``--perturb ... --problems ...``
in the perturbed worlds (a run's own plan, ``logs/to_result_<n>.npz`` beside its problem, is taken
when the case has none: the plan the run executed, not a re-solve).

Each case saves its plan (plan.npz) and its TO problem (problem.pkl, for the contact schedule) so
that ``--replay`` measures a controller change on the same plans in seconds instead of minutes.
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
for _p in ("src/lomanip_to", "src/lomanip_sim", "src/lomanip_planner", "src/lomanip_perception"):
    sys.path.insert(0, str(ROOT / _p))
os.environ.setdefault("MUJOCO_GL", "egl")

TASK = ROOT / "ros_ws/config/tasks/push_trolley.yaml"
#: whole-body controller gains of the executions (``--wbc NAME=VALUE`` overrides fields)
WBC_GAINS = None
VIDEO = False  # --video: each execution's MP4 (GIF without an encoder), frames and a strip
#: trolley chassis centre (m) per case; "base" is the demo's own layout
CASES = {"base": None, "near": [0.80, 0.0], "far_left": [0.90, 0.05], "right": [0.85, -0.05],
         # a second set of layouts, to check a change against plans it was not tuned on (--cases all)
         "far": [0.90, 0.0], "left": [0.85, 0.05], "near_right": [0.80, -0.05], "far_right": [0.90, -0.05]}
DEFAULT_CASES = ["base", "near", "far_left", "right"]
#: model errors for ``--perturb``: the saved plans executed in a world that differs from the one they
#: were planned in (scenario overrides, execution only). The plans assume an 8 kg trolley whose wheels
#: resist with 1.5 N each, at its measured place; a real trolley is none of these exactly. "closer" /
#: "farther" move the trolley 2 cm along its heading, so the hands meet the handle early / late
PERTURBATIONS = {"nominal": {}, "light": {"trolley_mass": 6.0}, "heavy": {"trolley_mass": 10.0},
                 "free_wheels": {"wheel_rolling_resistance": 0.75}, "stiff_wheels": {"wheel_rolling_resistance": 3.0},
                 "closer": {"trolley_shift": -0.02}, "farther": {"trolley_shift": 0.02},
                 # not a model error: MuJoCo's own defaults, the worlds before session 46 (a pyramidal
                 # cone, impratio 1: soft friction that lets a loaded sole creep; docs/execution.md)
                 "pyramidal": {"friction_cone": "pyramidal", "impratio": 1.0}}


def task_and_overrides(position) -> tuple[dict, dict]:
    """The demo's task file and its scenario overrides with the trolley at ``position`` (None: as is)."""
    task = yaml.safe_load(TASK.read_text())
    overrides = dict(task.get("scenario_overrides") or {})
    if position is not None:
        overrides["trolley_position"] = position
    return task, overrides


def task_options(task: dict, extra_options: dict):
    """TO options of the demo's task: solver.yaml, then the task file's, then ``extra_options``."""
    from lomanip_to import fixtures

    solver_yaml = yaml.safe_load(Path(fixtures.CONFIG_DIR, "solver.yaml").read_text())
    options = fixtures.load_options(solver_yaml.get("options"))
    options = fixtures.load_options(task.get("options"), options)
    return fixtures.load_options(extra_options, options)


def save_plan(case_dir: Path, res, problem) -> None:
    """plan.npz (TOResult.load reads it back) and problem.pkl (our own file, read by --replay only)."""
    case_dir.mkdir(parents=True, exist_ok=True)
    res.save(case_dir / "plan.npz")
    with open(case_dir / "problem.pkl", "wb") as f:
        pickle.dump(problem, f)


def problem_case_name(path: Path) -> str:
    """runs/<run>/logs/to_problem_1.pkl -> '<run>_1' (the file's stem elsewhere)."""
    if path.parent.name == "logs" and path.stem.startswith("to_problem_"):
        return f"{path.parent.parent.name}_{path.stem.rsplit('_', 1)[-1]}"
    return path.stem


def seed_from_run(path: Path, out_root: Path) -> None:
    """A graph run's own plan as a case (``--replay`` / ``--perturb`` with ``--problems``): copies
    logs/to_result_<n>.npz and to_problem_<n>.pkl to <out>/<run>_<n>/ unless that case has a plan."""
    import shutil

    case_dir = out_root / problem_case_name(path)
    result = path.with_name(path.name.replace("to_problem_", "to_result_")).with_suffix(".npz")
    if (case_dir / "plan.npz").is_file() or not result.is_file():
        return
    case_dir.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(result, case_dir / "plan.npz")
    shutil.copyfile(path, case_dir / "problem.pkl")


def solve_saved_problem(path: Path, extra_options: dict, out_root: Path) -> dict:
    """Re-solve a graph run's saved TO problem with the task's options, then execute it."""
    from lomanip_to import solver

    task, overrides = task_and_overrides(None)
    with open(path, "rb") as f:
        problem = pickle.load(f)
    problem.options = task_options(task, extra_options)
    name = problem_case_name(path)
    t0 = time.perf_counter()
    res = solver.solve(problem)
    row = {"case": name, "problem": str(path), "to_status": res.stats.status, "to_success": bool(res.success),
           "to_iterations": res.stats.iterations, "plan_time_s": round(time.perf_counter() - t0, 1)}
    save_plan(out_root / name, res, problem)
    if not res.success:
        return row
    return execute(row, res, problem, task["scenario"], overrides, out_root / name)


def run_case(name: str, position, extra_options: dict, out_root: Path) -> dict:
    from lomanip_planner import offline

    task, overrides = task_and_overrides(position)
    options = task_options(task, extra_options)
    t0 = time.perf_counter()
    plan = offline.plan(task["scenario"], task["prompts"], overrides=overrides, options=options)
    res = plan.result
    row = {"case": name, "trolley_position": overrides.get("trolley_position"), "to_status": res.stats.status,
           "to_success": bool(res.success), "to_iterations": res.stats.iterations,
           "plan_time_s": round(time.perf_counter() - t0, 1)}
    save_plan(out_root / name, res, plan.problem)
    if not res.success:
        return row
    return execute(row, res, plan.problem, task["scenario"], overrides, out_root / name)


def execute(row: dict, res, problem, scenario: str, overrides: dict, out_dir: Path) -> dict:
    """Run a plan under physics in the scenario's world; ``row`` + the execution metrics."""
    from lomanip_sim.execution import Execution
    from lomanip_sim.media import save_run
    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.simulator import Simulation
    from lomanip_sim.trajectory import from_to_result

    res.densify()
    traj = from_to_result(res, problem.phases, scenario=scenario)
    ex = Execution(Simulation(load_scenario(scenario, overrides)), traj, gains=WBC_GAINS)
    m = ex.run()
    save_run(out_dir, ex, out_dir.name, video=VIDEO)
    row.update(m.as_dict())
    return row


def perturbed(overrides: dict, perturbation: dict) -> dict:
    """Scenario overrides with a ``PERTURBATIONS`` entry applied (``trolley_shift``: m along x)."""
    from lomanip_sim.scenario import S2TrolleyParams

    out = dict(overrides)
    for key, val in perturbation.items():
        if key == "trolley_shift":
            x, y = out.get("trolley_position") or S2TrolleyParams().trolley_position
            out["trolley_position"] = [float(x) + val, float(y)]  # (the push heads along +x)
        else:
            out[key] = val
    return out


def replay_case(name: str, position, out_root: Path, perturbation: dict | None = None) -> dict:
    """Execute the plan a previous run saved for ``name`` (no TO), in a world changed by ``perturbation``."""
    from lomanip_to.result import TOResult

    task, overrides = task_and_overrides(position)
    overrides = perturbed(overrides, perturbation or {})
    case_dir = out_root / name
    if not (case_dir / "plan.npz").is_file() or not (case_dir / "problem.pkl").is_file():
        raise FileNotFoundError(f"{case_dir} holds no saved plan (plan.npz + problem.pkl): run without --replay first")
    res = TOResult.load(case_dir / "plan.npz")
    with open(case_dir / "problem.pkl", "rb") as f:
        problem = pickle.load(f)
    row = {"case": name, "trolley_position": overrides.get("trolley_position"), "to_status": res.stats.status,
           "to_success": bool(res.success), "to_iterations": res.stats.iterations, "plan_time_s": 0.0}
    if not res.success:
        return row
    return execute(row, res, problem, task["scenario"], overrides, case_dir if not perturbation else
                   case_dir / "perturb" / "_".join(f"{k}{v}" for k, v in perturbation.items()))


def _value(text: str):
    """YAML value of a command-line override; numbers like 1e4 (a string to YAML 1.1) as floats."""
    v = yaml.safe_load(text)
    if isinstance(v, str):
        try:
            return float(v)
        except ValueError:
            return v
    return v


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="*", default=DEFAULT_CASES, choices=[*CASES, "all"],
                    help=f"layouts (default {' '.join(DEFAULT_CASES)}; 'all' adds {' '.join(c for c in CASES if c not in DEFAULT_CASES)})")
    ap.add_argument("--set", action="append", default=[], metavar="OPTION=YAML",
                    help="override a TO option of the task, e.g. max_cmp_offset=0 (repeatable)")
    ap.add_argument("--out", default="runs/bench_push")
    ap.add_argument("--wbc", action="append", default=[], metavar="GAIN=YAML",
                    help="override a WbcGains field of the controller, e.g. w_contact=1e4 (repeatable)")
    ap.add_argument("--video", action="store_true", help="save a video, frames and a strip of each execution")
    ap.add_argument("--replay", action="store_true", help="execute the plans saved under --out again (no TO)")
    ap.add_argument("--perturb", nargs="+", default=[], choices=[*PERTURBATIONS, "all"],
                    help="execute the saved plans (as --replay) in worlds with model errors; prints the trolley's travel per case and error")
    ap.add_argument("--problems", nargs="+", default=[], metavar="PKL",
                    help="instead of the layouts: re-solve TO problems saved by graph runs (runs/<run>/logs/to_problem_*.pkl)")
    args = ap.parse_args()
    extra = {}
    for item in args.set:
        key, sep, val = item.partition("=")
        if not sep:
            print(f"bench_push: --set expects OPTION=VALUE, got {item!r}", file=sys.stderr)
            return 2
        extra[key] = _value(val)
    global WBC_GAINS, VIDEO
    VIDEO = args.video
    from dataclasses import fields, replace

    from lomanip_sim.wbc import WbcGains

    names = {f.name for f in fields(WbcGains)}
    gains = {}
    for item in args.wbc:
        key, sep, val = item.partition("=")
        if not sep or key not in names:
            print(f"bench_push: --wbc expects GAIN=VALUE with a WbcGains field, got {item!r}", file=sys.stderr)
            return 2
        gains[key] = _value(val)
    WBC_GAINS = replace(WbcGains(), **gains)
    missing = [p for p in args.problems if not Path(p).is_file()]
    if missing:
        print(f"bench_push: no such problem file: {missing[0]}", file=sys.stderr)
        return 2
    if "all" in args.cases:
        args.cases = list(CASES)
    out_root = ROOT / args.out
    out_root.mkdir(parents=True, exist_ok=True)
    if args.replay or args.perturb:
        for p in args.problems:
            seed_from_run(Path(p), out_root)
    if args.perturb:   # the layouts' saved plans, or those of --problems (as --replay --problems)
        cases = [problem_case_name(Path(p)) for p in args.problems] or args.cases
        return perturb_table(cases, list(PERTURBATIONS) if "all" in args.perturb else args.perturb,
                             out_root, gains)
    jobs = [(problem_case_name(Path(p)), Path(p)) for p in args.problems] or [(n, None) for n in args.cases]
    width = max([10] + [len(n) + 1 for n, _ in jobs])
    print(f"{'case':<{width}}{'TO':>22}{'it':>6}{'plan s':>8}{'fell':>6}{'end s':>7}{'trolley':>9}"
          f"{'pelvis max/rms cm':>19}{'success':>9}")
    rows = []
    for name, path in jobs:
        try:
            if args.replay:
                row = replay_case(name, CASES.get(name), out_root)
            elif path is not None:
                row = solve_saved_problem(path, extra, out_root)
            else:
                row = run_case(name, CASES[name], extra, out_root)
        except FileNotFoundError as e:
            print(f"bench_push: {e}", file=sys.stderr)
            return 2
        rows.append(row)
        if "fell" not in row:
            print(f"{name:<{width}}{row['to_status'][:21]:>22}{row['to_iterations']:>6}{row['plan_time_s']:>8.0f}  not executed")
            continue
        trolley = row["task_success_detail"].split("trolley moved ")[-1].split(" m")[0]
        print(f"{name:<{width}}{row['to_status'][:21]:>22}{row['to_iterations']:>6}{row['plan_time_s']:>8.0f}"
              f"{str(row['fell']):>6}{row['duration']:>7.2f}{trolley:>9}"
              f"{100 * row['max_base_position_error']:>10.1f}/{100 * row['rms_base_position_error']:<8.1f}"
              f"{str(row['task_success']):>9}")
    done = [r for r in rows if "fell" in r]
    print(f"executed without a fall {sum(not r['fell'] for r in done)}/{len(rows)}; task success "
          f"{sum(bool(r.get('task_success')) for r in done)}/{len(rows)}; outputs under {out_root}")
    (out_root / ("summary_replay.json" if args.replay else "summary.json")).write_text(json.dumps({"options": extra, "wbc": gains, "rows": rows}, indent=2, default=str))
    return 0


def perturb_table(cases: list[str], names: list[str], out_root: Path, gains: dict) -> int:
    """Each saved plan executed in each perturbed world: trolley travel (m), F = fell, * = task failed."""
    print("trolley travel (m) per saved plan and model error; F fell, * task failed (planned 0.25 m)")
    width = max([12] + [len(c) + 1 for c in cases])
    print(f"{'case':<{width}}" + "".join(f"{n:>14}" for n in names))
    rows, ok = [], {n: 0 for n in names}
    for case in cases:
        cells = []
        for n in names:
            try:
                row = replay_case(case, CASES.get(case), out_root, PERTURBATIONS[n])
            except FileNotFoundError as e:
                print(f"bench_push: {e}", file=sys.stderr)
                return 2
            row["perturbation"] = n
            rows.append(row)
            if "fell" not in row:
                cells.append("no plan")
                continue
            travel = row["task_success_detail"].split("trolley moved ")[-1].split(" m")[0]
            ok[n] += bool(row["task_success"])
            cells.append(f"{travel}{' F' if row['fell'] else ''}{'' if row['task_success'] else ' *'}")
        print(f"{case:<{width}}" + "".join(f"{c:>14}" for c in cells), flush=True)
    print(f"{'success':<{width}}" + "".join(f"{f'{ok[n]}/{len(cases)}':>14}" for n in names))
    (out_root / "summary_perturb.json").write_text(json.dumps({"wbc": gains, "perturbations": {n: PERTURBATIONS[n] for n in names},
                                                              "rows": rows}, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
