"""Send a task to the planner's `/lomanip/plan` action, show its progress, wait for the result.

Used by `lomanip plan`. It only uses the public interface (lomanip_msgs), like a user's own client.
Ctrl-C cancels the goal on the planner and waits (briefly) for it to acknowledge.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import rclpy
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Point
from rclpy.action import ActionClient
from rclpy.node import Node

from lomanip_launch.task_file import Task
from lomanip_msgs.action import Plan
from lomanip_msgs.msg import (CostWeight, ErrorCode, PlacementGoal, ScenarioParameters, SolverOption, SubtaskOptions,
                              TrajectoryOptions)

import yaml


class PlanClientError(RuntimeError):
    """The plan could not be sent or did not come back; one line for the user."""


@dataclass
class PlanOutcome:
    result: Plan.Result
    status: int
    seconds: float

    @property
    def succeeded(self) -> bool:
        return self.status == GoalStatus.STATUS_SUCCEEDED and self.result.error_code.val == ErrorCode.SUCCESS


def goal_from_task(task: Task, execute: bool = False) -> Plan.Goal:
    goal = Plan.Goal()
    goal.prompts = list(task.prompts)
    goal.placement_goals = [PlacementGoal(object_id=g.object_id, position=Point(x=g.position[0], y=g.position[1],
                                                                                z=g.position[2]), yaw=g.yaw)
                            for g in task.placement_goals]
    overrides = yaml.safe_dump(task.scenario_overrides, default_flow_style=True).strip() if task.scenario_overrides else ""
    goal.scenario = ScenarioParameters(name=task.scenario, overrides_yaml=overrides)
    options = TrajectoryOptions()
    for key, value in task.options.items():
        if key == "solver_options":
            options.solver_options = [SolverOption(name=k, value=v) for k, v in value.items()]
        elif key == "weights":
            options.weights = [CostWeight(name=k, value=float(v)) for k, v in value.items()]
        elif key == "subtask_options":
            options.subtask_options = [SubtaskOptions(subtask_index=int(k), options_yaml=yaml.safe_dump(
                v, default_flow_style=True, width=10**6).strip()) for k, v in sorted(value.items())]
        else:
            setattr(options, key, type(getattr(options, key))(value))
    goal.options = options
    goal.execute = execute
    return goal


class _Progress:
    """A tqdm bar driven by Plan feedback (stage, subtask, TO iteration); log lines instead when
    the bar is off or stderr is not a terminal (a bar redrawn into a file or a CI log is one line
    per TO iteration: 80 kB for the demo's push)."""

    def __init__(self, enabled: bool):
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=100, unit="%", bar_format="{l_bar}{bar}| {elapsed} {postfix}")
        self.last = ""

    def update(self, fb: Plan.Feedback) -> None:
        text = f"{fb.stage} {fb.subtask_index + 1}/{fb.subtask_count}"
        if self.bar is None:
            # log lines: each new stage, then one line per 10 TO iterations or per 5 % of the execution
            line = text
            if fb.stage == "optimisation" and fb.iteration:
                line += f" it {fb.iteration // 10 * 10}"
            elif fb.stage == "execution":
                line += f" {int(fb.progress * 20)}"
            if line != self.last:
                print(f"[lomanip] {text}: {fb.message}", flush=True)
            self.last = line
            return
        if fb.stage == "optimisation" and fb.iteration:
            text += f" it {fb.iteration}"
        self.bar.n = int(round(100 * min(max(fb.progress, 0.0), 1.0)))
        self.bar.set_description(text)
        self.bar.set_postfix_str(fb.message[:60])
        self.last = text

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_plan(task: Task, timeout: float, execute: bool = False, progress_bar: bool = True,
             node: Node | None = None, should_stop=lambda: False) -> PlanOutcome:
    """Send ``task`` as a Plan goal and wait up to ``timeout`` s for its result (rclpy must be initialised)."""
    own = node is None
    node = node or rclpy.create_node("lomanip_plan_client")
    client = ActionClient(node, Plan, "/lomanip/plan")
    bar = _Progress(progress_bar)
    handle = None
    try:
        if not client.wait_for_server(timeout_sec=30.0):
            raise PlanClientError("the planner's /lomanip/plan action is not available (is lomanip_planner running?)")
        t0 = time.monotonic()
        send = client.send_goal_async(goal_from_task(task, execute), feedback_callback=lambda m: bar.update(m.feedback))
        rclpy.spin_until_future_complete(node, send, timeout_sec=30.0)
        handle = send.result()
        if handle is None:
            raise PlanClientError("the planner did not answer the goal request within 30 s")
        if not handle.accepted:
            raise PlanClientError("the planner rejected the goal (another plan is running)")
        result_future = handle.get_result_async()
        deadline = t0 + timeout
        try:
            while not result_future.done():
                if time.monotonic() > deadline:
                    _cancel(node, handle)
                    raise PlanClientError(f"no plan result within {timeout:.0f} s; the goal was cancelled")
                if should_stop():
                    _cancel(node, handle)
                    raise PlanClientError("interrupted; the goal was cancelled on the planner")
                rclpy.spin_once(node, timeout_sec=0.1)
        except KeyboardInterrupt:
            _cancel(node, handle)
            raise
        wrapped = result_future.result()
        return PlanOutcome(wrapped.result, wrapped.status, time.monotonic() - t0)
    finally:
        bar.close()
        client.destroy()
        if own:
            node.destroy_node()


def _cancel(node: Node, handle) -> None:
    future = handle.cancel_goal_async()
    rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
