#!/usr/bin/env python3
"""Benchmark of physics execution (issue 6): TO results executed by the whole-body controller.

Every case is a TO result executed under MuJoCo physics with torques only (lomanip_sim.execution):
the TO fixtures solved here (case_stand, case_one_step, case_lift_box, optionally s1_basket /
s2_trolley with --problems), and every runs/bench_to/*.npz written by tools/bench_to.py
(``TOResult.load``; the fixture is the config name that starts the file name, the grid overrides
come from runs/bench_to/summary.json). A plan whose
fixture names a lomanip_sim scenario runs in that scenario's world (S1/S2 task success); the others
in a world built from the plan's own scene. Prints per case: TO convergence, task success, fell,
max/RMS pelvis position and joint tracking error, final object position error, real-time factor
(unpaced: simulated time / wall time of physics + control), the largest contact force on a robot
link other than the feet and hands ("unplanned N": the plan has no such contact), where the plan's own
configurations already overlap the simulator's meshes (lomanip_sim.plan_geometry: the deepest
body-on-object, self and arm-on-object overlap, 5 mm or more, none simulated), and saves under runs/bench_exec/<case>/
a video (MP4, or GIF without an MP4 encoder), PNG frames, tracking.png, forces.png, metrics.json.

    .venv/bin/python tools/bench_exec.py                          # the three TO test cases (~2.5 min)
    .venv/bin/python tools/bench_exec.py --cases case_stand --problems s1_basket
    .venv/bin/python tools/bench_exec.py --cases --gains '{"grasp_squeeze_scale": 2.0}'   # controller gains
    .venv/bin/python tools/bench_exec.py --cases --bench-to runs/bench_to \
        --world box_mass=2.0 --world box_mass=3.0 --world trolley_mass=6.0,wheel_rolling_resistance=3.0

``--world`` executes every plan once more in a world with model errors: scenario overrides applied
to the simulated world only, the plan unchanged (it was made for the world its benchmark solved; a
case solved here is solved once). The small cases have no scenario: they take the keys every
scenario has (MuJoCo's options, e.g. ``--world friction_cone=elliptic,impratio=10``). Each such run
is labelled ``<case>@<overrides>``; a world key the scenario does not have is refused with a one-line
error before anything runs.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
for _p in ("src/lomanip_sim", "src/lomanip_to"):
    sys.path.insert(0, str(ROOT / _p))

FIXTURES = ("case_stand", "case_one_step", "case_lift_box")


def plan_world(problem: str, overrides: dict, prob, traj_start, world: dict | None = None):
    """(Simulation, scenario name) for a plan: the fixture's lomanip_sim scenario, or its own scene;
    ``world``: scenario keys changed in the simulated world only (--world)."""
    from lomanip_sim import scene_world
    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.simulator import Simulation
    from lomanip_to import fixtures

    raw = yaml.safe_load(Path(fixtures.config_path(problem)).read_text())
    if raw.get("scenario"):
        _params, sim_over = fixtures._scenario_params(raw, overrides)
        return Simulation(load_scenario(raw["scenario"], {**sim_over, **(world or {})})), raw["scenario"]
    built = scene_world.build_scene_world(scene_world.objects_from_to_problem(prob), robot_qpos=traj_start,
                                          params=scene_world.scene_params(world))
    return Simulation(built), problem


def _problem_of(stem: str) -> str:
    """The fixture a saved result belongs to: the longest config name that starts its file stem."""
    from lomanip_to import fixtures

    names = [p.stem for p in Path(fixtures.CONFIG_DIR).glob("*.yaml")]
    match = [n for n in names if stem == n or stem.startswith(n + "_")]
    return max(match, key=len) if match else stem


def cases(args) -> list[tuple[str, str, dict, Path | None]]:
    """(case label, fixture problem name, overrides, saved result path or None to solve here)."""
    out = [(c, c, {}, None) for c in args.cases] + [(p, p, {}, None) for p in args.problems]
    bench_to = ROOT / args.bench_to
    overrides = saved_overrides(bench_to)
    for npz in sorted(bench_to.glob("*.npz")) if bench_to.is_dir() else []:
        out.append((npz.stem, _problem_of(npz.stem), overrides.get(npz.stem, {}), npz))
    return out


def saved_task(saved: Path) -> str:
    """The task file a saved result was planned from (tools/bench_plan.py's <out>/to/summary.json;
    for results saved before it recorded one, the task its ``<scenario>_prompts_`` name gives, where
    such a task file exists), or "" for a fixture's result."""
    summary = saved.parent / "summary.json"
    rows = json.loads(summary.read_text()) if summary.is_file() else {}
    rows = rows.get("rows", []) if isinstance(rows, dict) else []
    task = next((r.get("task") or "" for r in rows if f"{r['case']}_{r['variant']}" == saved.stem), "")
    if not task and "_prompts_" in saved.stem:
        guess = saved.stem.split("_prompts_")[0]
        task = guess if (ROOT / "ros_ws/config/tasks" / f"{guess}.yaml").is_file() else ""
    return task


def prompts_problem(task: str, overrides: dict, horizon: float):
    """The TO problem of a plan from prompts, rebuilt from its task file as tools/bench_plan.py built
    it (perception and retargeting are deterministic); ValueError if its horizon is not the saved
    result's (the result is from older code or another task).

    Why: the controller takes its contact states from the plan's schedule, and a plan from prompts
    has its own (S1's: 22.2 s, 49 phases since session 53), not the fixture's (18.2 s). Before session 52 these
    results were executed with the fixture's schedule."""
    import bench_plan   # tools/ is on sys.path when run as a script
    from lomanip_planner import offline

    spec = bench_plan.load_task(task)
    plan = offline.plan(spec["scenario"], spec["prompts"], bench_plan.placement_goals(spec), overrides,
                        solve=False)
    if abs(plan.problem.duration - horizon) > 1e-6:
        raise ValueError(f"task {task!r} rebuilt gives a {plan.problem.duration:.2f} s plan, the saved result "
                         f"is {horizon:.2f} s long: planned with other code or inputs")
    return plan.problem


def saved_overrides(folder: Path) -> dict[str, dict]:
    """Saved result stem (``<case>_<variant>``) -> the grid overrides it was solved at, from the
    folder's summary.json (tools/bench_to.py, tools/bench_plan.py's <out>/to); {} without one."""
    summary = folder / "summary.json"
    rows = json.loads(summary.read_text()) if summary.is_file() else {}
    rows = rows.get("rows", []) if isinstance(rows, dict) else []
    return {f"{r['case']}_{r['variant']}": dict(r.get("overrides") or {}) for r in rows}


def parse_worlds(specs: list[str]) -> list[dict]:
    """``--world`` values (``KEY=VALUE[,KEY=VALUE]``, YAML values) as override dicts; ValueError
    naming the bad item."""
    worlds = []
    for spec in specs:
        world = {}
        for item in re.split(r",(?=\s*[A-Za-z_]\w*\s*=)", spec):  # commas inside [a, b] stay
            key, sep, value = item.partition("=")
            if not sep or not key.strip():
                raise ValueError(f"bad --world item {item!r} (want KEY=VALUE, e.g. box_mass=3.0)")
            world[key.strip()] = yaml.safe_load(value)
        worlds.append(world)
    return worlds


def check_worlds(worlds: list[dict], problems: set[str]) -> None:
    """Every ``--world`` key must be a parameter of each scenario it will change (ValueError if not);
    a fixture without a lomanip_sim scenario (the small cases) takes the physics keys every scenario has."""
    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.scene_world import scene_params
    from lomanip_to import fixtures

    for problem in sorted(problems):
        scenario = yaml.safe_load(Path(fixtures.config_path(problem)).read_text()).get("scenario")
        for world in worlds:
            try:
                load_scenario(scenario, world) if scenario else scene_params(world)
            except ValueError as e:  # lomanip_sim.scenario.ScenarioError: unknown key, bad value
                raise ValueError(f"--world {world} for {scenario or problem}: {e}") from None


def world_label(world: dict) -> str:
    return ",".join(f"{k}={v}" for k, v in world.items())


def run_case(label: str, problem: str, overrides: dict, saved: Path | None, out_root: Path, video: bool,
             gains=None, world: dict | None = None, solved: dict | None = None) -> dict:
    """Execute one plan (saved, or solved here; ``solved`` caches the latter by fixture for --world)."""
    from lomanip_sim.execution import Execution
    from lomanip_sim.media import save_run
    from lomanip_sim.plan_geometry import plan_penetrations
    from lomanip_sim.trajectory import TrajectoryError, from_to_result
    from lomanip_to import fixtures, solver
    from lomanip_to.result import TOResult

    prob = fixtures.load_problem(problem, overrides)
    solved = {} if solved is None else solved
    if saved is not None:
        res, solve_s = TOResult.load(saved), 0.0
    elif problem in solved:
        res, solve_s = solved[problem]
    else:
        t0 = time.perf_counter()
        res = solver.solve(prob)
        res, solve_s = solved.setdefault(problem, (res, time.perf_counter() - t0))
    if res.t is None:
        res.densify()
    row = {"case": label, "problem": problem, "overrides": overrides, "world": dict(world or {}),
           "to_converged": bool(res.success), "to_time_s": round(solve_s, 1) if saved is None else None}
    task = saved_task(saved) if saved is not None else ""
    try:
        if task:   # planned from prompts (tools/bench_plan.py): its own schedule, not the fixture's
            prob = prompts_problem(task, overrides, float(res.t_knots[-1]))
    except ValueError as e:
        row.update(error=str(e))
        return row
    try:
        traj = from_to_result(res, prob.phases)
        sim, scenario = plan_world(problem, overrides, prob, traj.qpos(0), world)
        traj.scenario = scenario
        overlaps = plan_penetrations(sim, traj, min_depth=0.005)
        ex = Execution(sim, traj, gains=gains)
    except TrajectoryError as e:
        row.update(error=f"{e.code}: {e.message}")
        return row
    m = ex.run()
    files = save_run(out_root / label, ex, label, video=video)
    row.update(m.as_dict(), plan_duration=traj.duration, files=files)
    # deepest of each kind (lomanip_sim.plan_geometry), before anything is simulated
    row["plan_mesh_overlaps"] = {k: str(next(p for p in overlaps if p.kind == k))
                                 for k in ("body", "self", "arm") if any(p.kind == k for p in overlaps)}
    return row


def gains_from_json(text: str):
    """WbcGains with the overrides of a JSON object (``--gains``); ValueError saying what is wrong."""
    from lomanip_sim.wbc import WbcGains

    try:
        return WbcGains(**json.loads(text))
    except (TypeError, ValueError) as e:
        raise ValueError(f"bad --gains: {e}") from None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="*", default=list(FIXTURES), help="TO fixtures to solve and execute")
    ap.add_argument("--problems", nargs="*", default=[], help="more fixtures (e.g. s1_basket s2_trolley)")
    ap.add_argument("--bench-to", default="runs/bench_to", help="folder of saved TO results (*.npz)")
    ap.add_argument("--out", default="runs/bench_exec")
    ap.add_argument("--no-video", action="store_true")
    ap.add_argument("--gains", default="{}", help='WbcGains overrides as JSON, e.g. \'{"grasp_squeeze_scale": 2.0}\'')
    ap.add_argument("--world", action="append", default=[], metavar="KEY=VALUE[,KEY=VALUE]",
                    help="also execute every plan in a world with these scenario overrides (model errors or "
                         "MuJoCo's options, the plan unchanged; repeatable), e.g. --world box_mass=3.0")
    args = ap.parse_args()
    try:
        gains = gains_from_json(args.gains)
        worlds = parse_worlds(args.world)
    except ValueError as e:
        print(f"bench_exec: {e}", file=sys.stderr)
        return 2
    todo = cases(args)
    if worlds:
        try:
            check_worlds(worlds, {problem for _l, problem, _o, _saved in todo})
        except ValueError as e:
            print(f"bench_exec: {e}", file=sys.stderr)
            return 2
    runs = [(c, None) for c in todo]
    runs += [(c, w) for c in todo for w in worlds]
    solved: dict = {}  # fixture -> (result, solve time): a case solved here is executed in every world
    out_root = ROOT / args.out
    out_root.mkdir(parents=True, exist_ok=True)
    rows = []
    width = max([28] + [len(c[0]) + len(world_label(w or {})) + 3 for c, w in runs])
    hdr = (f"{'case':<{width}}{'TO':>5}{'success':>9}{'fell':>6}{'base max/rms cm':>17}{'joint max/rms rad':>19}"
           f"{'obj cm/tilt rad':>16}{'RTF':>6}{'QPfail':>7}{'unplanned N':>12}")
    print(hdr)
    for (label, problem, overrides, saved), world in runs:
        if world is not None:
            label = f"{label}@{world_label(world)}"
        row = run_case(label, problem, overrides, saved, out_root, not args.no_video, gains, world, solved)
        rows.append(row)
        if "error" in row:
            print(f"{label:<{width}}{'yes' if row['to_converged'] else 'no':>5}  refused: {row['error']}")
            continue
        print(f"{label:<{width}}{'yes' if row['to_converged'] else 'no':>5}{str(row['task_success']):>9}{str(row['fell']):>6}"
              f"{100 * row['max_base_position_error']:>9.2f}/{100 * row['rms_base_position_error']:<7.2f}"
              f"{row['max_joint_error']:>10.3f}/{row['rms_joint_error']:<8.3f}"
              f"{100 * row['final_object_position_error']:>10.1f}/{row['final_object_tilt_error']:<5.2f}"
              f"{row['real_time_factor']:>6.2f}{row['qp_failures']:>7d}{row['max_unplanned_contact_force']:>12.0f}")
        print(f"    {row['task_success_detail']}")
        for kind, what in row["plan_mesh_overlaps"].items():
            print(f"    the plan's own meshes overlap ({kind}): {what}")
        if row["unplanned_contact"]:
            print(f"    largest unplanned contact: {row['max_unplanned_contact_force']:.0f} N, {row['unplanned_contact']}")
    ok = [r for r in rows if r.get("task_success")]
    print(f"task success {len(ok)}/{len(rows)}; fell {sum(bool(r.get('fell')) for r in rows)}; "
          f"outputs under {out_root}")
    (out_root / "summary.json").write_text(json.dumps(rows, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
