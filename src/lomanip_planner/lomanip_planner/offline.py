"""The plan pipeline without ROS: scenario -> perception -> retargeting -> schedule -> TO.

Why: the planner node runs these stages over services; the benchmark (tools/bench_plan.py) and the
tests need the same stages in one process, on the same inputs the node gets: the simulated world
(objects, the standing robot after it settled, one RGB-D frame of the scene camera) and the
perception configuration file. Nothing here imports rclpy.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from lomanip_sim import frames
from lomanip_sim.robot_model import G1_JOINT_NAMES

from .keyframes import SubtaskPerception, build_problem, retarget_subtasks, stance_from_qpos, x_from_qpos
from .retargeting import LimbTarget, Retargeter, pelvis_height_ratio
from .schedule import FLOOR, Schedule, SubtaskKeyframe

#: s of simulated standing before the robot state is read (what the node sees a moment after start)
SETTLE_TIME = 0.5


@dataclass
class ScenarioState:
    """What the planner node reads from the sim: objects, robot qpos, one camera frame."""

    name: str
    objects: list          # lomanip_to.problem.SceneObject
    qpos: np.ndarray       # 36, MuJoCo order
    perception_scene: object  # lomanip_perception.pipeline.SceneInput


@dataclass
class OfflinePlan:
    state: ScenarioState
    perception: list = field(default_factory=list)         # lomanip_perception SubtaskResult per prompt
    keyframes: list[SubtaskKeyframe] = field(default_factory=list)
    schedule: Schedule | None = None
    problem: object | None = None                           # lomanip_to.problem.Problem
    result: object | None = None                            # lomanip_to.result.TOResult
    timings: dict[str, float] = field(default_factory=dict)


def scenario_state(scenario: str, overrides: dict | None = None) -> ScenarioState:
    """Build the scenario world, let the robot stand for SETTLE_TIME, render the scene camera."""
    from lomanip_perception.datatypes import PerceptionImage, PinholeCamera, RigidPose
    from lomanip_perception.evaluation import object_from_state
    from lomanip_perception.pipeline import SceneInput
    from lomanip_sim.camera import RGBDCamera
    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.simulator import Simulation
    from lomanip_to.scene import objects_from_world

    sim = Simulation(load_scenario(scenario, overrides or {}))
    sim.step(max(1, round(SETTLE_TIME / sim.timestep)))
    snap = sim.snapshot()
    with RGBDCamera(sim.model, sim.world.camera_name) as cam:
        frame = cam.render(snap.qpos, snap.time)
    k = frame.intrinsics
    image = PerceptionImage(frame.rgb, frame.depth, PinholeCamera(k.width, k.height, k.fx, k.fy, k.cx, k.cy),
                            RigidPose(frame.pose.R_optical, frame.pose.position), source="simulator")
    objects, _ = objects_from_world(sim.world)
    qpos = np.asarray(sim.robot_qpos(), float)
    return ScenarioState(scenario, objects, qpos,
                         SceneInput(image, [object_from_state(o) for o in sim.scene_objects()]))


def subtasks_from_results(results, prompts: list[str]) -> list[SubtaskPerception]:
    """Perception results -> retargeting inputs (the core twin of conversions.subtasks_from_perception)."""
    by_index = {r.index: r for r in results}
    out = []
    for i, prompt in enumerate(prompts):
        r = by_index.get(i)
        if r is None:
            out.append(SubtaskPerception(i, prompt, []))
            continue
        contacts = [LimbTarget(c.limb, np.asarray(c.position, float), np.asarray(c.normal, float),
                               c.object_id or FLOOR) for c in r.contacts]
        yaw = frames.quat_to_yaw(np.asarray(r.root_quat, float))
        prior = {n: float(a) for n, a in zip(r.joint_names, r.joint_angles) if n in G1_JOINT_NAMES}
        out.append(SubtaskPerception(i, prompt, contacts, frames.yaw_to_quat(yaw), prior,
                                     pelvis_height_ratio(r.keypoints_world)))
    return out


def plan(scenario: str, prompts: list[str], placements: dict | None = None, overrides: dict | None = None,
         perception_config: dict | None = None, retargeter: Retargeter | None = None, options=None,
         solve: bool = True, progress=None) -> OfflinePlan:
    """Run every stage; ``options`` are lomanip_to Options (keyframe ablations go there).

    Raises the stage's own error (PerceptionError, RetargetingError, ScheduleError, ProblemError);
    a TO that does not converge is returned with ``result.success`` False, never raised.
    """
    from lomanip_perception.config import build_from_config, load_config
    from lomanip_perception.pipeline import PerceptionPipeline

    out = OfflinePlan(scenario_state(scenario, overrides))
    t0 = time.perf_counter()
    models, transfer, seed = build_from_config(perception_config or load_config())
    pipeline = PerceptionPipeline(models, transfer, seed)
    out.perception = pipeline.run(list(prompts), out.state.perception_scene)
    out.timings["perception"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    retargeter = retargeter or Retargeter()
    stance = stance_from_qpos(retargeter, out.state.qpos)
    subtasks = subtasks_from_results(out.perception, list(prompts))
    out.keyframes = retarget_subtasks(subtasks, out.state.objects, stance, retargeter, placements or {},
                                      out.state.qpos)
    out.problem, out.schedule = build_problem(out.state.objects, out.keyframes, stance,
                                              x_from_qpos(out.state.qpos), options=options, name=scenario)
    out.timings["retargeting"] = time.perf_counter() - t0
    if solve:
        from lomanip_to import solver

        t0 = time.perf_counter()
        out.result = solver.solve(out.problem, progress=progress)
        out.timings["optimisation"] = time.perf_counter() - t0
    return out
