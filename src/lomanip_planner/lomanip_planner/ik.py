"""Keyframe IK as a descent: mink's QP gives the step, an acceptance test makes it a solver.

Differential IK integrated with a fixed step is a controller, not a solver: with many competing
tasks and active limits its full Gauss-Newton steps overshoot, the iterate keeps oscillating
(S1's pick keyframe moved 0.25-2.5 rad per step after 400 iterations) and where it stops at the
iteration cap depends chaotically on its inputs (a 1e-9 m change of a hand target moved that
keyframe by 2.6 rad). Here every task's error is a fixed function of the configuration and a QP
step is kept only if it lowers the weighted task cost (Levenberg-Marquardt damping otherwise), so
the cost falls monotonically and the result moves continuously with the targets. The tail is slow
where only the weak posture prior is left to settle: S1's keyframes typically reach the iteration
cap with the cost still falling by a few 1e-4 of itself per 100 steps. A descent can therefore stop
when it stalls (``stall_window`` steps that lower the cost by less than ``stall_tolerance`` of it),
which the retargeter does: the tail cost 60-80 % of its IK time for well under 1 % of the cost
(session 35). DescentResult says which stop it was.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import mink
import mujoco
import numpy as np
import qpsolvers

from .balance import combined_com


class ComOverFeetTask(mink.Task):
    """Horizontal CoM over the midpoint of two foot sites, where the feet are now.

    The target moves with the feet (feet may slide on the floor), so it is part of the error and
    of its Jacobian instead of a target reset every iteration. With a load (:meth:`set_load`: a
    point mass held at a fixed place, as an object in the hands) the CoM is the robot's and the
    load's together.
    """

    def __init__(self, feet: Sequence[str], cost: float = 1.0) -> None:
        super().__init__(cost=np.full(2, cost), gain=1.0, lm_damping=0.0)
        self.feet = tuple(feet)
        self.load_mass = 0.0
        self.load_point = np.zeros(3)

    def set_load(self, mass: float = 0.0, point: np.ndarray | None = None) -> None:
        """A point load (kg, world m) counted in the CoM; ``mass`` 0 removes it."""
        self.load_mass = max(float(mass), 0.0)
        self.load_point = np.zeros(3) if point is None else np.asarray(point, float).copy()

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        mid = np.mean([configuration.data.site(f).xpos for f in self.feet], axis=0)
        com = combined_com(float(configuration.model.body_subtreemass[1]), configuration.data.subtree_com[1],
                           self.load_mass, self.load_point)
        return com[:2] - mid[:2]

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        model, data = configuration.model, configuration.data
        jac = np.zeros((3, model.nv))
        mujoco.mj_jacSubtreeCom(model, data, jac, 1)
        robot = float(model.body_subtreemass[1])
        jac *= robot / (robot + self.load_mass)   # the load does not move with q
        for f in self.feet:
            jac_site = np.zeros((3, model.nv))
            mujoco.mj_jacSite(model, data, jac_site, None, model.site(f).id)
            jac -= jac_site / len(self.feet)
        return jac[:2]


class PelvisFloorTask(mink.Task):
    """One-sided pull: the pelvis origin no lower than ``height``; no cost above it, or, with a
    ``ceiling``, none up to it and a pull down above it.

    The error min(0, z - height) + max(0, z - ceiling) is continuously differentiable when
    squared, so the descent sees one smooth cost instead of a task switched on and off between
    iterations.
    """

    def __init__(self, height: float, cost: float, ceiling: float | None = None) -> None:
        super().__init__(cost=np.array([cost]), gain=1.0, lm_damping=0.0)
        self.height = float(height)
        self.ceiling = np.inf if ceiling is None else max(float(ceiling), self.height)

    def compute_error(self, configuration: mink.Configuration) -> np.ndarray:
        z = configuration.data.body("pelvis").xpos[2]
        return np.array([min(0.0, z - self.height) + max(0.0, z - self.ceiling)])

    def compute_jacobian(self, configuration: mink.Configuration) -> np.ndarray:
        model, data = configuration.model, configuration.data
        if self.height <= data.body("pelvis").xpos[2] <= self.ceiling:
            return np.zeros((1, model.nv))
        jac = np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, jac, None, model.body("pelvis").id)
        return jac[2:3]


def task_cost(configuration: mink.Configuration, tasks: Sequence[mink.Task]) -> float:
    """Half the weighted squared task error, the function mink's QP models to second order."""
    total = 0.0
    for task in tasks:
        weighted = np.asarray(task.cost) * task.compute_error(configuration)
        total += 0.5 * float(weighted @ weighted)
    return total


@dataclass(frozen=True)
class DescentResult:
    iterations: int
    cost: float
    converged: bool   # stopped at a stationary point (or stalled), not at the iteration cap or a QP failure
    stalled: bool = False   # stopped because ``stall_window`` steps barely lowered the cost


def minimise(configuration: mink.Configuration, tasks: Sequence[mink.Task], limits: Sequence[mink.Limit],
             *, solver: str = "daqp", damping: float = 1e-3, max_iterations: int = 400,
             tolerance: float = 1e-12, stall_window: int = 0, stall_tolerance: float = 1e-3) -> DescentResult:
    """Minimise :func:`task_cost` from the configuration's current q, in place (Levenberg-Marquardt).

    Each iteration solves mink's QP (tasks + limits + ``damping`` on the diagonal) for a step and
    compares the cost's actual drop with the QP model's predicted one: a step that does not lower
    the cost is refused and the damping raised; a good one is kept and the damping lowered. A
    scaled step stays inside the limits' linearised constraints (they hold at dq = 0), so damping
    never makes the QP infeasible. Stops when the predicted drop is below ``tolerance``, or (with
    ``stall_window`` > 0) when the last ``stall_window`` iterations together lowered the cost by less
    than ``stall_tolerance`` * cost. Relative, not absolute: the weak posture prior alone costs
    about 1e-4, and an absolute floor stopped the push keyframe before it had settled its knees.
    """
    dt = 1.0   # the QP's variable is a displacement; mink divides by dt, so use 1
    cost = task_cost(configuration, tasks)
    lam = damping
    history = [cost]
    for iteration in range(1, max_iterations + 1):
        q0 = configuration.q.copy()
        while True:
            problem = mink.build_ik(configuration, tasks, dt, damping=lam, limits=limits)
            solution = qpsolvers.solve_problem(problem, solver=solver)
            if not solution.found:
                return DescentResult(iteration, cost, False)
            dq = solution.x
            predicted = -(0.5 * float(dq @ problem.P @ dq) + float(problem.q @ dq))
            if predicted < tolerance * (1.0 + cost):
                return DescentResult(iteration, cost, True)
            configuration.integrate_inplace(dq, dt)
            trial = task_cost(configuration, tasks)
            ratio = (cost - trial) / predicted
            if ratio > 1e-4:
                cost = trial
                break
            configuration.update(q0)
            lam *= 4.0
            if lam > 1e8:   # no step lowers the cost: stationary to first order
                return DescentResult(iteration, cost, True)
        if ratio > 0.75:
            lam = max(lam / 3.0, 1e-9)
        elif ratio < 0.25:
            lam *= 2.0
        history.append(cost)
        if stall_window > 0 and len(history) > stall_window and \
                history[-1 - stall_window] - cost < stall_tolerance * cost:
            return DescentResult(iteration, cost, True, stalled=True)
    return DescentResult(max_iterations, cost, False)
