"""lomanip_planner node: the user-facing plan service and action.

  /lomanip/plan               lomanip_msgs/srv/PlanTask     prompt list in, trajectory out
  /lomanip/plan               lomanip_msgs/action/Plan      the same, with progress feedback; cancellable
  /lomanip/keyframes          lomanip_msgs/KeyframeArray    (latched) keyframes of the last plan
  /lomanip/contact_schedule   lomanip_msgs/ContactSchedule  (latched)

Subscribes /lomanip/to/progress (lomanip_msgs/SolverStatistics, one per TO iteration, rate-limited by
lomanip_to) to forward the TO iteration into the action feedback. With ``execute`` the trajectory
is then run under physics through the sim's /lomanip/sim/execute action (lomanip_msgs/action/Execute).

Sequence: optional scenario reset (/lomanip/sim/reset) -> perception (/lomanip/perception/
extract_contacts) -> retargeting and contact schedule (in this process) -> trajectory optimisation
(/lomanip/to/optimize, which also publishes /lomanip/trajectory). One plan at a time: a request
while one runs is answered BUSY; the running plan is not disturbed. Every stage has a timeout
(parameters ``*_timeout``); a stage that fails ends the plan with that stage's error code.
"""
from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import rclpy
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage

from lomanip_msgs.action import Execute, Plan
from lomanip_msgs.msg import ContactSchedule, ErrorCode, KeyframeArray, SceneObjects, SolverStatistics, StageTiming
from lomanip_msgs.srv import ExtractContacts, OptimizeTrajectory, PlanTask, ResetScenario

from . import conversions as conv
from .timeouts import optimisation_timeout

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class PlanFailed(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


@dataclass
class Progress:
    stage: str
    subtask_index: int = 0
    subtask_count: int = 0
    iteration: int = 0
    progress: float = 0.0
    message: str = ""


def _speeds(pelvis_track: list[tuple[float, np.ndarray]], joints: JointState) -> tuple[float | None, float]:
    """Pelvis speed over the last >= 0.2 s of /tf (None until that much is seen) and the largest joint speed."""
    joint_speed = float(np.max(np.abs(joints.velocity))) if len(joints.velocity) else 0.0
    if len(pelvis_track) < 2:
        return None, joint_speed
    t1, p1 = pelvis_track[-1]
    for t0, p0 in reversed(pelvis_track[:-1]):
        if t1 - t0 >= 0.2:
            return float(np.linalg.norm(p1 - p0) / (t1 - t0)), joint_speed
    return None, joint_speed


class PlannerNode(Node):
    def __init__(self) -> None:
        super().__init__("lomanip_planner")
        self.timeouts = {stage: float(self.declare_parameter(f"{stage}_timeout", default).value)
                         for stage, default in (("state", 10.0), ("reset", 60.0), ("perception", 300.0), ("retargeting", 60.0),
                                                ("optimisation", 900.0), ("execution", 600.0))}
        self.push_distance = float(self.declare_parameter("push_distance", 0.25).value)
        # Plan from a robot that stands still: after a reset the standing controller moves the pelvis
        # about 2 cm over 1.5 s, and planning from a moving snapshot made keyframes differ run to run.
        self.settle_timeout = float(self.declare_parameter("settle_timeout", 10.0).value)
        self.settle_base_speed = float(self.declare_parameter("settle_base_speed", 0.001).value)
        self.settle_joint_speed = float(self.declare_parameter("settle_joint_speed", 0.01).value)
        from .retargeting import Retargeter

        self.retargeter = Retargeter()
        self._busy = threading.Lock()
        self._scene: SceneObjects | None = None
        self._joints: JointState | None = None
        self._pelvis = None
        self._pelvis_track: list[tuple[float, np.ndarray]] = []   # (stamp s, position) while waiting for state
        self._to_progress: Callable[[SolverStatistics], None] | None = None
        group = self._group = ReentrantCallbackGroup()
        self.create_subscription(SceneObjects, "/lomanip/scene_objects", self._on_scene, LATCHED, callback_group=group)
        # /joint_states (100 Hz) and /tf (50 Hz) are subscribed only while a request waits for the
        # robot's state (_wait_for_state): kept open they cost this node a third of a core in
        # rclpy, taken from the TO solving beside it on a 2-core machine
        self.create_subscription(SolverStatistics, "/lomanip/to/progress", self._on_to_progress, 10,
                                 callback_group=group)
        self.pub_keyframes = self.create_publisher(KeyframeArray, "/lomanip/keyframes", LATCHED)
        self.pub_schedule = self.create_publisher(ContactSchedule, "/lomanip/contact_schedule", LATCHED)
        self.cli_reset = self.create_client(ResetScenario, "/lomanip/sim/reset", callback_group=group)
        self.cli_perception = self.create_client(ExtractContacts, "/lomanip/perception/extract_contacts",
                                                 callback_group=group)
        self.cli_to = self.create_client(OptimizeTrajectory, "/lomanip/to/optimize", callback_group=group)
        self.cli_to_cancel = self.create_client(Trigger, "/lomanip/to/cancel", callback_group=group)
        self.cli_execute = ActionClient(self, Execute, "/lomanip/sim/execute", callback_group=group)
        self.create_service(PlanTask, "/lomanip/plan", self._on_plan_service, callback_group=group)
        self._action = ActionServer(self, Plan, "/lomanip/plan", execute_callback=self._on_plan_action,
                                    goal_callback=self._on_goal, cancel_callback=lambda _: CancelResponse.ACCEPT,
                                    callback_group=group)
        self.get_logger().info("plan service and action ready on /lomanip/plan")

    # --- state from the sim ----------------------------------------------------------------------
    def _on_scene(self, msg: SceneObjects) -> None:
        self._scene = msg

    def _on_joints(self, msg: JointState) -> None:
        self._joints = msg

    def _on_tf(self, msg: TFMessage) -> None:
        for t in msg.transforms:
            if t.header.frame_id == "world" and t.child_frame_id == "pelvis":
                self._pelvis = t.transform
                p = t.transform.translation
                self._pelvis_track.append((t.header.stamp.sec + 1e-9 * t.header.stamp.nanosec, np.array([p.x, p.y, p.z])))
                del self._pelvis_track[:-50]

    def _wait_for_state(self) -> None:
        """The robot's current joints and pelvis pose, from fresh /joint_states and /tf messages,
        once the robot stands still (or after ``settle_timeout`` s, with a warning)."""
        self._joints = self._pelvis = None
        self._pelvis_track.clear()
        # no QoS event handlers on these: rclpy does not guard an event handler whose subscription is
        # destroyed while the executor waits on it, and that race crashed this node (InvalidHandle
        # in executor.spin) in a graph test; the subscription handles themselves are guarded
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        subs = [self.create_subscription(JointState, "/joint_states", self._on_joints, 10, callback_group=self._group,
                                         event_callbacks=quiet),
                self.create_subscription(TFMessage, "/tf", self._on_tf, 10, callback_group=self._group,
                                         event_callbacks=quiet)]
        try:
            deadline = time.monotonic() + self.timeouts["state"]
            while self._scene is None or self._joints is None or self._pelvis is None:
                if time.monotonic() > deadline:
                    missing = [name for name, v in (("/lomanip/scene_objects", self._scene), ("/joint_states", self._joints),
                                                    ("/tf world->pelvis", self._pelvis)) if v is None]
                    raise PlanFailed(ErrorCode.NOT_READY, f"no data from the simulator on {', '.join(missing)} "
                                     f"after {self.timeouts['state']:.0f} s; is lomanip_sim running?")
                time.sleep(0.05)
            t0 = time.monotonic()
            while True:
                base, joints = _speeds(self._pelvis_track, self._joints)
                if base is not None and base < self.settle_base_speed and joints < self.settle_joint_speed:
                    self.get_logger().info(f"robot still after {time.monotonic() - t0:.1f} s (pelvis {base * 1e3:.1f} mm/s, "
                                           f"joints up to {joints:.3f} rad/s)")
                    return
                if time.monotonic() - t0 > self.settle_timeout:
                    self.get_logger().warning(
                        f"robot still moving after {self.settle_timeout:.0f} s (pelvis {1e3 * (base or 0.0):.1f} mm/s, "
                        f"joints up to {joints:.3f} rad/s); planning from its current state")
                    return
                time.sleep(0.05)
        finally:
            for sub in subs:
                self.destroy_subscription(sub)

    def _on_to_progress(self, msg: SolverStatistics) -> None:
        sink = self._to_progress
        if sink is not None:
            sink(msg)

    # --- entry points ----------------------------------------------------------------------------
    def _on_goal(self, goal) -> GoalResponse:
        return GoalResponse.REJECT if self._busy.locked() else GoalResponse.ACCEPT

    def _on_plan_service(self, request: PlanTask.Request, response: PlanTask.Response):
        return self._run(request, response, feedback=None, cancelled=lambda: False)

    def _on_plan_action(self, goal_handle):
        result = Plan.Result()

        def feedback(p: Progress) -> None:
            goal_handle.publish_feedback(Plan.Feedback(stage=p.stage, subtask_index=p.subtask_index,
                                                       subtask_count=p.subtask_count, iteration=p.iteration,
                                                       progress=p.progress, message=p.message))

        self._run(goal_handle.request, result, feedback, lambda: goal_handle.is_cancel_requested)
        if goal_handle.is_cancel_requested:
            goal_handle.canceled()
        elif result.error_code.val == ErrorCode.SUCCESS:
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return result

    def _run(self, request, response, feedback: Callable[[Progress], None] | None, cancelled: Callable[[], bool]):
        if not self._busy.acquire(blocking=False):
            response.error_code = ErrorCode(val=ErrorCode.BUSY, message="a plan is already running; try again later")
            return response
        try:
            self._plan(request, response, feedback or (lambda p: None), cancelled)
        except PlanFailed as exc:
            response.error_code = ErrorCode(val=exc.code, message=str(exc))
            self.get_logger().warning(f"plan failed: {exc}")
        finally:
            self._busy.release()
        return response

    # --- the pipeline ------------------------------------------------------------------------------
    def _call(self, client, request, stage: str, cancelled: Callable[[], bool], timeout: float | None = None):
        timeout = self.timeouts[stage] if timeout is None else float(timeout)
        if not client.wait_for_service(timeout_sec=min(10.0, timeout)):
            raise PlanFailed(ErrorCode.NOT_READY, f"{stage}: service {client.srv_name} is not available")
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        deadline = time.monotonic() + timeout
        while not done.wait(0.2):
            if cancelled():
                future.cancel()
                if stage == "optimisation" and self.cli_to_cancel.service_is_ready():
                    self.cli_to_cancel.call_async(Trigger.Request())   # stop the TO's worker too
                raise PlanFailed(ErrorCode.CANCELLED, f"cancelled during {stage}")
            if time.monotonic() > deadline:
                future.cancel()
                raise PlanFailed(ErrorCode.TIMEOUT, f"{stage} did not answer within {timeout:.0f} s")
        return future.result()

    def _plan(self, request, response, feedback, cancelled) -> None:
        from lomanip_to.conversions import request_from_problem, schedule_msg, scene_from_msg
        from lomanip_to.problem import ProblemError

        from .keyframes import build_problem, retarget_subtasks, stance_from_qpos, x_from_qpos
        from .retargeting import RetargetingError
        from .schedule import ScheduleError

        log = self.get_logger()
        prompts = [p.strip() for p in request.prompts]
        if not prompts or any(not p for p in prompts):
            raise PlanFailed(ErrorCode.INVALID_REQUEST, "prompts must be a non-empty list of non-empty strings")
        n = len(prompts)
        timings: list[StageTiming] = []

        def stage_done(name: str, t0: float) -> None:
            timings.append(StageTiming(stage=name, seconds=time.perf_counter() - t0))
            response.timings = list(timings)

        if request.scenario.name:
            t0 = time.perf_counter()
            feedback(Progress("reset", 0, n, message=f"resetting to {request.scenario.name}"))
            self._scene = None
            res = self._call(self.cli_reset, ResetScenario.Request(scenario=request.scenario), "reset", cancelled)
            stage_done("reset", t0)
            if res.error_code.val != ErrorCode.SUCCESS:
                raise PlanFailed(res.error_code.val, f"reset: {res.error_code.message}")
            self._scene = res.scene
            time.sleep(0.2)   # let /joint_states and /tf report the new world
        self._wait_for_state()

        known = {o.id: o for o in self._scene.objects}
        for g in request.placement_goals:
            if g.object_id not in known:
                raise PlanFailed(ErrorCode.UNKNOWN_OBJECT, f"placement goal for {g.object_id!r}, which is not in the "
                                 f"scene (objects: {', '.join(sorted(known))})")
            if not known[g.object_id].movable:
                raise PlanFailed(ErrorCode.INVALID_REQUEST, f"placement goal for {g.object_id!r}, which is fixed")
            if not all(np.isfinite([g.position.x, g.position.y, g.position.z, g.yaw])):
                raise PlanFailed(ErrorCode.INVALID_REQUEST, f"placement goal for {g.object_id!r} is not finite")

        t0 = time.perf_counter()
        feedback(Progress("perception", 0, n, progress=0.05, message="extracting contacts"))
        log.info(f"planning {n} subtasks: {prompts}")
        per = self._call(self.cli_perception, ExtractContacts.Request(prompts=prompts), "perception", cancelled)
        stage_done("perception", t0)
        if per.error_code.val != ErrorCode.SUCCESS:
            raise PlanFailed(per.error_code.val, f"perception: {per.error_code.message}")
        response.contacts, response.human_poses = per.contacts, per.human_poses

        t0 = time.perf_counter()
        feedback(Progress("retargeting", 0, n, progress=0.3, message="retargeting keyframes"))
        try:
            objects = scene_from_msg(self._scene)
            qpos = conv.robot_qpos(self._joints, self._pelvis)
            stance = stance_from_qpos(self.retargeter, qpos)
            subtasks = conv.subtasks_from_perception(per.contacts, per.human_poses, prompts)
            placements = {g.object_id: conv.placement_goal(g) for g in request.placement_goals}
            keyframes = retarget_subtasks(subtasks, objects, stance, self.retargeter, placements, qpos,
                                          push_distance=self.push_distance)
            problem, schedule = build_problem(objects, keyframes, stance, x_from_qpos(qpos),
                                              name=self._scene.scenario)
        except (RetargetingError, ScheduleError, ProblemError) as exc:
            raise PlanFailed(getattr(exc, "code", ErrorCode.RETARGETING_INFEASIBLE), f"retargeting: {exc}") from exc
        for kf in keyframes:
            lb = kf.load_balance
            if lb is not None:
                log.info(f"keyframe {kf.index} ({kf.prompt!r}) holds {lb.mass:.1f} kg: balance margin "
                         f"{lb.margin_before * 100:+.1f} -> {lb.margin_after * 100:+.1f} cm, feet stepped "
                         f"{np.linalg.norm(lb.shift) * 100:.1f} cm")
        log.info(f"stance left {np.round(stance.left, 3).tolist()} right {np.round(stance.right, 3).tolist()}; "
                 f"schedule {problem.duration:.1f} s: " + ", ".join(
                     f"{ph.phase_type[0]}{ph.end - ph.start:.1f}" for ph in problem.phases))
        kf_msg = conv.keyframe_array_msg(problem.keyframes, self.get_clock().now().to_msg())
        response.keyframes = kf_msg
        self.pub_keyframes.publish(kf_msg)
        self.pub_schedule.publish(schedule_msg(problem.phases))
        stage_done("retargeting", t0)
        if cancelled():
            raise PlanFailed(ErrorCode.CANCELLED, "cancelled after retargeting")

        t0 = time.perf_counter()
        feedback(Progress("optimisation", n - 1, n, progress=0.5,
                          message=f"optimising {problem.duration:.1f} s, {len(problem.phases)} phases"))
        to_request = request_from_problem(problem, self.retargeter_joint_names())
        to_request.scene = self._scene
        to_request.options = request.options

        def to_progress(msg: SolverStatistics) -> None:
            feedback(Progress("optimisation", n - 1, n, iteration=msg.iterations, progress=0.5,
                              message=f"TO iteration {msg.iterations}: objective {msg.cost:.3e}, constraint "
                                      f"violation {msg.max_dynamics_violation:.1e} [{msg.status_message}]"))

        self._to_progress = to_progress
        to_timeout = optimisation_timeout(self.timeouts["optimisation"], request.options.time_limit)
        if to_timeout > self.timeouts["optimisation"]:
            log.info(f"optimisation: waiting up to {to_timeout:.0f} s (the TO's hard deadline for its "
                     f"{request.options.time_limit:.0f} s time limit; optimisation_timeout is "
                     f"{self.timeouts['optimisation']:.0f} s)")
        try:
            res = self._call(self.cli_to, to_request, "optimisation", cancelled, timeout=to_timeout)
        finally:
            self._to_progress = None
        stage_done("optimisation", t0)
        if res.error_code.val != ErrorCode.SUCCESS:
            response.trajectory.solver_statistics = res.trajectory.solver_statistics
            raise PlanFailed(res.error_code.val, f"optimisation: {res.error_code.message}")
        response.trajectory = res.trajectory
        if request.execute:
            t0 = time.perf_counter()
            self._execute(res.trajectory, response, feedback, cancelled, n)
            stage_done("execution", t0)
        feedback(Progress("done", n - 1, n, progress=1.0, message="trajectory ready"))
        response.error_code = ErrorCode(val=ErrorCode.SUCCESS, message=res.error_code.message)
        log.info("plan ready: " + ", ".join(f"{t.stage} {t.seconds:.1f} s" for t in timings))

    def _execute(self, trajectory, response, feedback, cancelled, n: int) -> None:
        """Run the trajectory under physics on the sim's Execute action; fills response.execution."""
        timeout = self.timeouts["execution"]
        if not self.cli_execute.wait_for_server(timeout_sec=min(10.0, timeout)):
            raise PlanFailed(ErrorCode.NOT_READY, "execution: action /lomanip/sim/execute is not available")
        points = trajectory.joint_trajectory.points
        duration = points[-1].time_from_start.sec + 1e-9 * points[-1].time_from_start.nanosec if points else 0.0

        def on_feedback(fb) -> None:
            f = fb.feedback
            feedback(Progress("execution", n - 1, n, progress=0.9 + 0.1 * f.progress,
                              message=f"t={f.time_from_start:.1f} s, base error {f.base_position_error * 100:.1f} cm, "
                                      f"joint RMS error {f.joint_error_rms:.3f} rad"))

        feedback(Progress("execution", n - 1, n, progress=0.9, message=f"executing {duration:.1f} s under physics"))
        done = threading.Event()
        goal_future = self.cli_execute.send_goal_async(Execute.Goal(trajectory=trajectory), feedback_callback=on_feedback)
        goal_future.add_done_callback(lambda _: done.set())
        if not done.wait(10.0):
            raise PlanFailed(ErrorCode.TIMEOUT, "execution: the sim did not accept the goal within 10 s")
        handle = goal_future.result()
        if handle is None or not handle.accepted:
            raise PlanFailed(ErrorCode.BUSY, "execution: the sim rejected the goal (another execution runs?)")
        done.clear()
        result_future = handle.get_result_async()
        result_future.add_done_callback(lambda _: done.set())
        deadline = time.monotonic() + timeout
        while not done.wait(0.2):
            if cancelled() or time.monotonic() > deadline:
                handle.cancel_goal_async()
                done.wait(10.0)
                if cancelled():
                    raise PlanFailed(ErrorCode.CANCELLED, "cancelled during execution (the robot stands)")
                raise PlanFailed(ErrorCode.TIMEOUT, f"execution did not finish within {timeout:.0f} s")
        result = result_future.result().result
        response.execution = result.metrics
        if result.error_code.val != ErrorCode.SUCCESS:
            raise PlanFailed(result.error_code.val, f"execution: {result.error_code.message}")

    @staticmethod
    def retargeter_joint_names() -> list[str]:
        from lomanip_sim.robot_model import G1_JOINT_NAMES

        return list(G1_JOINT_NAMES)


def main(argv: list[str] | None = None) -> int:
    rclpy.init(args=argv if argv is not None else sys.argv)
    node = None
    try:
        node = PlannerNode()
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
