"""How long the planner and its clients wait for the TO: at least as long as the request allows it.

Why: a task's TO time limit (``TrajectoryOptions.time_limit``, set in its task file) is the one knob
for how long a plan may take. The planner's ``optimisation_timeout`` parameter and the plan client's
wait are floors; a request whose TO may run longer (S1 from its prompts needs 20-35 minutes on 2 cores)
stretches them to the TO's hard deadline, so the planner never answers TIMEOUT for a solve the TO
node would still finish or stop itself.
"""
from __future__ import annotations

from lomanip_to.solver_process import hard_deadline

#: lomanip_msgs/TrajectoryOptions.time_limit's default (s)
DEFAULT_TIME_LIMIT = 600.0
#: s the planner waits past the TO node's hard deadline (the result's conversion and transfer)
TO_ANSWER_MARGIN = 60.0
#: s a plan client allows beyond the optimisation for the other stages (perception, retargeting,
#: reset, settle; execution is added on its own)
OTHER_STAGES = 600.0
#: s a plan client allows for the execution under physics (the planner's execution_timeout default)
EXECUTION = 600.0


def optimisation_timeout(configured: float, time_limit: float) -> float:
    """The planner's wait for the TO node: its parameter, or the TO's hard deadline + margin if later."""
    if not time_limit > 0.0:
        return float(configured)
    return max(float(configured), hard_deadline(time_limit) + TO_ANSWER_MARGIN)


def plan_wait(options: dict, execute: bool, floor: float = 1800.0) -> float:
    """A plan client's wait for the whole Plan action of a task whose TO options are ``options``."""
    limit = float(options.get("time_limit", DEFAULT_TIME_LIMIT))
    wait = optimisation_timeout(0.0, limit) + OTHER_STAGES + (EXECUTION if execute else 0.0)
    return max(float(floor), wait)
