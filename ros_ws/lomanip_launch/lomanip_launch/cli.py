"""The `lomanip` command: start the graph, record it, summarise bags, run the demo.

    lomanip up [--scenario s1_basket] [--set box_mass=5.0] [--record runs/bag] [--duration 10]
    lomanip bag info runs/bag
    lomanip plan [TASK | --prompt P ...] [--record] [--execute]
    lomanip demo
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from datetime import datetime
from pathlib import Path

import yaml

from lomanip_launch.environment import apply_to_current_process, default_params_file, lomanip_environment
from lomanip_launch.process_graph import GraphError, NodeSpec, ProcessGraph

EXIT_USAGE = 2
EXIT_GRAPH = 3


class UsageError(ValueError):
    """Bad command-line input; reported as one line and exit code 2."""


def _parse_overrides(items: list[str]) -> dict:
    overrides = {}
    for item in items:
        if "=" not in item:
            raise UsageError(f"--set expects KEY=VALUE, got {item!r}")
        key, value = item.split("=", 1)
        overrides[key.strip()] = yaml.safe_load(value)
    return overrides


def _check_params_file(path: Path) -> dict:
    if not path.is_file():
        raise UsageError(f"parameter file {path} does not exist")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        raise UsageError(f"parameter file {path} is not valid YAML ({where.strip() or 'parse error'}: "
                         f"{getattr(exc, 'problem', exc)})") from exc
    if not isinstance(data, dict) or not all(isinstance(v, dict) and "ros__parameters" in v
                                             for v in data.values()):
        raise UsageError(f"parameter file {path} must map node names to {{ros__parameters: {{...}}}}")
    return data


def _validate_scenario(name: str, overrides: dict) -> None:
    from lomanip_sim.scenario import ScenarioError, load_scenario

    try:
        load_scenario(name, overrides or None)
    except ScenarioError as exc:
        raise UsageError(str(exc)) from exc


def build_graph(args: argparse.Namespace, run_dir: Path) -> ProcessGraph:
    params_file = Path(args.params)
    params = _check_params_file(params_file)
    sim_params = params.get("lomanip_sim", {}).get("ros__parameters", {})
    scenario = args.scenario or sim_params.get("scenario", "s1_basket")
    overrides = _parse_overrides(args.set or [])
    _validate_scenario(scenario, overrides)
    python = sys.executable
    ros_args = ["--ros-args", "--params-file", str(params_file), "-p", f"scenario:={scenario}"]
    if overrides:
        # A YAML string parameter: quoted, or rcl would parse the mapping itself and refuse it.
        text = yaml.safe_dump(overrides, default_flow_style=True, width=1 << 20).strip()
        ros_args += ["-p", "scenario_overrides:='" + text.replace("'", "''") + "'"]
    for item in getattr(args, "sim_params", None) or []:   # e.g. "camera_rate:=1.0" (lomanip plan)
        ros_args += ["-p", item]
    specs = [NodeSpec("lomanip_sim", [python, "-m", "lomanip_sim.sim_node", *ros_args]),
             NodeSpec("lomanip_perception", [python, "-m", "lomanip_perception.perception_node", "--ros-args",
                                             "--params-file", str(params_file)]),
             NodeSpec("lomanip_to", [python, "-m", "lomanip_to.to_node", "--ros-args", "--params-file", str(params_file),
                                     "-p", f"problem_dir:={run_dir / 'logs'}"]),
             NodeSpec("lomanip_planner", [python, "-m", "lomanip_planner.planner_node", "--ros-args",
                                          "--params-file", str(params_file)])]
    exclude = list(getattr(args, "record_exclude", None) or [])
    if args.record:
        bag = Path(args.record)
        if bag.exists():
            raise UsageError(f"bag folder {bag} already exists; choose a new one")
        specs.append(NodeSpec("lomanip_recorder", [python, "-m", "lomanip_launch.recorder_node", str(bag),
                                                   *(["--exclude", *exclude] if exclude else [])]))
    graph = ProcessGraph(specs, lomanip_environment(), run_dir / "logs")
    graph.record_exclude = tuple(exclude)
    return graph


def _ros_node_names():
    """A readiness probe: the names of the nodes currently in the ROS graph."""
    import rclpy

    from rclpy.signals import SignalHandlerOptions

    apply_to_current_process()
    # The orchestrator handles Ctrl-C itself (stop the plan, then the nodes); rclpy's handler would
    # shut the context down under a running plan client.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    probe = rclpy.create_node("lomanip_orchestrator")

    def names() -> set[str]:
        rclpy.spin_once(probe, timeout_sec=0.05)
        return {name for name, _ in probe.get_node_names_and_namespaces()}

    def close() -> None:
        probe.destroy_node()
        rclpy.try_shutdown()

    def recorder_subscribed(patterns: tuple[str, ...], exclude: tuple[str, ...] = ()) -> bool:
        """True once every published topic the recorder should record has a subscriber."""
        from lomanip_launch.recorder_node import should_record

        rclpy.spin_once(probe, timeout_sec=0.05)
        topics = [t for t, _ in probe.get_topic_names_and_types() if should_record(t, patterns, exclude)]
        return bool(topics) and all(probe.count_subscribers(t) > 0 for t in topics
                                    if probe.count_publishers(t) > 0)

    names.recorder_subscribed = recorder_subscribed
    return names, close


#: s the orchestrator listens for nodes of another lomanip graph before it starts its own
DISCOVERY_WAIT = 2.0


def refuse_running_graph(names, ours: set[str], wait: float = DISCOVERY_WAIT) -> None:
    """GraphError if nodes named as ours are already in the ROS graph (another `lomanip` in the same
    ROS_DOMAIN_ID). Why: a second `lomanip demo` started beside a running `lomanip plan` sent its goal
    to the other graph's planner (answered busy) and its nodes shared names with the running ones."""
    deadline = time.monotonic() + wait
    while True:
        taken = sorted(ours & names())
        if taken or time.monotonic() >= deadline:
            break
    if taken:
        domain = os.environ.get("ROS_DOMAIN_ID", "0")
        raise GraphError(f"another lomanip graph is running in ROS_DOMAIN_ID={domain} (its nodes: "
                         f"{', '.join(taken)}); stop it, or start this one with another ROS_DOMAIN_ID")


def run_graph(graph: ProcessGraph, duration: float | None, ready_timeout: float = 60.0,
              on_ready=None) -> int:
    """Start, wait for every node, run until Ctrl-C / duration / a node dies, stop everything."""
    stop = {"sig": None}

    def handler(signum, _frame):
        stop["sig"] = signum

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    graph.watch_shm()   # before our probe's participant: shutdown cleans what it leaves too
    names, close_probe = _ros_node_names()
    code = 0
    try:
        refuse_running_graph(names, {s.name for s in graph.specs})
        graph.start()
        graph.wait_ready(names, ready_timeout)
        if any(n.spec.name == "lomanip_recorder" for n in graph.nodes):
            from lomanip_launch.recorder_node import DEFAULT_TOPICS

            deadline = time.monotonic() + 15.0   # the recorder subscribes as topics appear
            exclude = tuple(getattr(graph, "record_exclude", ()))
            while not names.recorder_subscribed(DEFAULT_TOPICS, exclude) and time.monotonic() < deadline:
                graph.check()
                time.sleep(0.2)
        print("[lomanip] graph is up:\n  " + "\n  ".join(graph.status_lines()), flush=True)
        finished = on_ready(lambda: stop["sig"] is not None) if on_ready is not None else None
        if finished is not None:      # on_ready did the job (e.g. a plan) and gives the exit code
            code = finished
        end = time.monotonic() + duration if duration else None
        while finished is None and stop["sig"] is None and (end is None or time.monotonic() < end):
            graph.check()
            time.sleep(0.2)
        if stop["sig"] is not None:
            print(f"[lomanip] {signal.Signals(stop['sig']).name} received, stopping", flush=True)
    except GraphError as exc:
        print(f"[lomanip] error: {exc}", file=sys.stderr, flush=True)
        code = EXIT_GRAPH
    finally:
        # our own participant first: it maps the nodes' shared-memory ports it talks to, so with it
        # still alive the graph's clean-up had to leave a port a node left behind, stale once we exit
        close_probe()
        graph.shutdown()
        for s, h in previous.items():
            signal.signal(s, h)
        print("[lomanip] stopped:\n  " + "\n  ".join(graph.status_lines()), flush=True)
    return code


def cmd_up(args: argparse.Namespace) -> int:
    run_dir = Path(args.run_dir) / datetime.now().strftime("%Y%m%d-%H%M%S")
    graph = build_graph(args, run_dir)
    return run_graph(graph, args.duration)


def cmd_bag_info(args: argparse.Namespace) -> int:
    from lomanip_launch.bag import BagError, summarize_bag

    try:
        print(summarize_bag(Path(args.bag)).format())
    except BagError as exc:
        raise UsageError(str(exc)) from exc
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from lomanip_launch.demo import run_demo

    return run_demo(args)


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lomanip", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    def graph_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--scenario", help="s1_basket or s2_trolley (default: from the params file)")
        p.add_argument("--set", action="append", metavar="KEY=VALUE",
                       help="override a scenario parameter, e.g. --set box_mass=5.0 (repeatable)")
        p.add_argument("--params", default=str(default_params_file()), help="ROS 2 parameter file")
        p.add_argument("--record", metavar="DIR", help="record every lomanip topic to this bag folder")
        p.add_argument("--run-dir", default="runs", help="where logs and outputs go")

    up = sub.add_parser("up", help="start the graph and keep it running")
    graph_options(up)
    up.add_argument("--duration", type=float, help="stop after this many seconds")
    up.set_defaults(func=cmd_up)

    bag = sub.add_parser("bag", help="bag tools")
    bag_sub = bag.add_subparsers(dest="bag_command", required=True)
    info = bag_sub.add_parser("info", help="print topics, types, counts and duration of a bag")
    info.add_argument("bag")
    info.set_defaults(func=cmd_bag_info)

    from lomanip_launch.plan_cmd import add_parser as add_plan_parser

    add_plan_parser(sub)

    demo = sub.add_parser("demo", help="the main job (see README)")
    graph_options(demo)
    demo.add_argument("--duration", type=float, default=10.0, help="seconds to record")
    demo.add_argument("--task", default="push_trolley", help="task planned in step 2 (ros_ws/config/tasks/; "
                      "s1_basket is the paper's S1, not yet reliable through the graph: README, Status)")
    demo.add_argument("--no-plan", action="store_true", help="only step 1 (graph, bag, PNGs)")
    demo.add_argument("--execute", action=argparse.BooleanOptionalAction, default=True,
                      help="execute the plan under physics afterwards (default; --no-execute: plan only)")
    demo.add_argument("--no-progress", action="store_true", help="log lines instead of a progress bar (always, when stderr is not a terminal)")
    demo.set_defaults(func=cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = make_parser().parse_args(argv)
    try:
        return args.func(args)
    except UsageError as exc:
        print(f"lomanip: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
