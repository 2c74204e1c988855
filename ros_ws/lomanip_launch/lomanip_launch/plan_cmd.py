"""`lomanip plan`: start the graph, send a prompt list to /lomanip/plan, save the result.

    lomanip plan s1_basket                       # a task shipped in ros_ws/config/tasks/
    lomanip plan my_task.yaml --record           # your own task file; record the run to a bag
    lomanip plan --scenario s2_trolley --prompt "pick up the box from the table" --place box=0.9,-1.1,0.475

Outputs go to runs/<timestamp>/: summary.yaml, contacts.yaml, keyframes.yaml, trajectory.npz,
trajectory.png (see plan_outputs), task.yaml (the task as planned), logs/ of every node (with the TO
node's to_problem_<n>.pkl and to_result_<n>.npz), and bag/ with --record. The exit code is 0
only when the plan succeeded; otherwise one line names the stage and the reason.
"""
from __future__ import annotations

import argparse
from datetime import datetime
from pathlib import Path

import yaml

EXIT_PLAN_FAILED = 4


def task_from_args(args: argparse.Namespace):
    from lomanip_launch.cli import UsageError
    from lomanip_launch.task_file import Task, TaskFileError, load_task, task_from_dict

    try:
        if args.prompt:
            goals = []
            for item in args.place or []:
                oid, _, values = item.partition("=")
                numbers = [float(v) for v in values.split(",")] if values else []
                if not oid or len(numbers) not in (3, 4):
                    raise TaskFileError(f"--place expects OBJECT=x,y,z[,yaw], got {item!r}")
                goals.append({"object": oid, "position": numbers[:3], "yaw": numbers[3] if len(numbers) == 4 else 0.0})
            task = task_from_dict({"scenario": args.scenario or "s1_basket", "prompts": args.prompt,
                                   "placement_goals": goals}, "command line")
        else:
            task = load_task(args.task or "s1_basket")
            if args.scenario and args.scenario != task.scenario:
                raise TaskFileError(f"--scenario {args.scenario} contradicts the task file's scenario {task.scenario}")
    except (TaskFileError, ValueError) as exc:
        raise UsageError(str(exc)) from exc
    for item in args.set or []:
        key, _, value = item.partition("=")
        task.scenario_overrides[key.strip()] = yaml.safe_load(value)
    if args.max_iterations:
        task.options["max_iterations"] = args.max_iterations
    return task


def write_task(path: Path, task) -> None:
    """The task as this run planned it (command-line overrides included): its scenario and
    overrides let tools/exec_trace.py replay the run's plan in the same world."""
    from dataclasses import asdict

    path.parent.mkdir(parents=True, exist_ok=True)
    data = asdict(task)
    data["placement_goals"] = [{"object": p["object_id"], "position": list(p["position"]), "yaw": p["yaw"]}
                               for p in data["placement_goals"]]
    path.write_text(yaml.safe_dump(data, sort_keys=False, width=110), encoding="utf-8")


def cmd_plan(args: argparse.Namespace) -> int:
    from lomanip_launch.cli import build_graph, run_graph

    task = task_from_args(args)
    run_dir = Path(args.run_dir) / datetime.now().strftime("%Y%m%d-%H%M%S")
    args.scenario = task.scenario
    args.set = [f"{k}={v}" for k, v in task.scenario_overrides.items()]
    if args.record is True:
        args.record = str(run_dir / "bag")
    args.record_exclude = [] if args.record_camera else ["/lomanip/camera/"]
    # Perception renders its own frame on demand (/lomanip/sim/get_rgbd_frame); without camera
    # recording a 1 Hz stream leaves the CPU to the optimiser (15 Hz rendering costs most of a core).
    args.sim_params = [] if args.record_camera else ["camera_rate:=1.0"]
    graph = build_graph(args, run_dir)
    write_task(run_dir / "task.yaml", task)
    print(f"[lomanip] plan: {task.scenario}, {len(task.prompts)} subtasks: {task.prompts}", flush=True)

    def plan(stop_requested) -> int:
        from lomanip_launch.plan_client import PlanClientError, run_plan
        from lomanip_launch.plan_outputs import error_name, executed, save_plan
        from lomanip_planner.timeouts import plan_wait

        timeout = args.timeout if args.timeout is not None else plan_wait(task.options, args.execute)
        try:
            outcome = run_plan(task, timeout, execute=args.execute, progress_bar=not args.no_progress,
                               should_stop=stop_requested)
        except PlanClientError as exc:
            print(f"[lomanip] error: {exc}", flush=True)
            return EXIT_PLAN_FAILED
        files = save_plan(run_dir, task.prompts, outcome.result, outcome.seconds)
        timings = ", ".join(f"{t.stage} {t.seconds:.1f} s" for t in outcome.result.timings)
        print(f"[lomanip] stage timings: {timings}", flush=True)
        for path in files:
            print(f"[lomanip] wrote {path}", flush=True)
        if not outcome.succeeded:
            code = outcome.result.error_code
            print(f"[lomanip] plan failed ({error_name(code.val)}): {code.message}", flush=True)
            return EXIT_PLAN_FAILED
        stats = outcome.result.trajectory.solver_statistics
        n = len(outcome.result.trajectory.joint_trajectory.points)
        print(f"[lomanip] plan succeeded in {outcome.seconds:.1f} s: {n} trajectory points, "
              f"{stats.iterations} TO iterations, max penetration {1000 * stats.max_penetration:.1f} mm", flush=True)
        if executed(outcome.result):
            ex = outcome.result.execution
            print(f"[lomanip] executed under physics: task success {ex.task_success}, fell {ex.fell}, pelvis max "
                  f"{100 * ex.max_base_position_error:.1f} cm, real-time factor {ex.real_time_factor:.2f} "
                  f"({ex.task_success_detail})", flush=True)
        return 0

    return run_graph(graph, None, on_ready=plan)


def add_parser(sub) -> None:
    from lomanip_launch.environment import default_params_file

    p = sub.add_parser("plan", help="plan a prompt list end to end and save the result",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("task", nargs="?", help="task name (ros_ws/config/tasks/NAME.yaml) or path; default s1_basket")
    p.add_argument("--prompt", action="append", help="a subtask prompt (repeatable; replaces the task file)")
    p.add_argument("--place", action="append", metavar="OBJECT=x,y,z[,yaw]", help="placement goal (with --prompt)")
    p.add_argument("--scenario", help="s1_basket or s2_trolley (with --prompt)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a scenario parameter")
    p.add_argument("--params", default=str(default_params_file()), help="ROS 2 parameter file")
    p.add_argument("--record", nargs="?", const=True, metavar="DIR",
                   help="record the run to a bag (default folder: runs/<timestamp>/bag)")
    p.add_argument("--record-camera", action="store_true", help="also record the camera streams (large)")
    p.add_argument("--execute", action="store_true", help="execute the trajectory in the simulator afterwards")
    p.add_argument("--max-iterations", type=int, help="TO iteration limit")
    p.add_argument("--timeout", type=float, default=None,
                   help="s to wait for the plan result (default: from the task's TO time_limit, at least 1800)")
    p.add_argument("--no-progress", action="store_true", help="log lines instead of a progress bar (always, when stderr is not a terminal)")
    p.add_argument("--run-dir", default="runs", help="where outputs go")
    p.set_defaults(func=cmd_plan)
