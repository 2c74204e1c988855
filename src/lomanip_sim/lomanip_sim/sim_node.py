"""lomanip_sim node: the MuJoCo world of a scenario, published over ROS 2.

Physics runs on its own thread, paced to real time (parameter real_time_factor), with the standing
controller closing the loop every physics step. The camera renders on its own schedule from a copy
of the state, in a worker process (parameter camera_process; on a thread it slowed the physics
thread to a third of real time on 2 cores). Publishes:

  /lomanip/camera/rgb/image_raw     sensor_msgs/Image (rgb8)
  /lomanip/camera/depth/image_raw   sensor_msgs/Image (32FC1, metres)
  /lomanip/camera/{rgb,depth}/camera_info   sensor_msgs/CameraInfo
  /joint_states                     sensor_msgs/JointState (29 G1 joints, efforts = torques)
  /tf                               world -> pelvis, world -> every scene object
  /tf_static                        world -> scene_camera_optical
  /lomanip/scene_objects            lomanip_msgs/SceneObjects (latched, re-sent on reset)
  /diagnostics                      real-time factor, simulated time, fallen
Services:
  /lomanip/sim/reset                lomanip_msgs/srv/ResetScenario
  /lomanip/sim/get_rgbd_frame       lomanip_msgs/srv/GetRGBDFrame
Actions:
  /lomanip/sim/execute              lomanip_msgs/action/Execute: a whole-body trajectory tracked by the
                                    torque-level whole-body controller (lomanip_sim.wbc) inside the
                                    physics loop; checked before anything moves; feedback at ~10 Hz;
                                    cancel (or a reset) hands the robot to the standing controller.
"""
from __future__ import annotations

import contextlib
import sys
import threading
import time

import lomanip_sim  # noqa: F401  (selects a headless GL backend before mujoco loads)
import mujoco  # noqa: E402
import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from rcl_interfaces.msg import ParameterDescriptor  # noqa: E402
from rclpy.action import ActionServer, CancelResponse, GoalResponse  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup  # noqa: E402
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image, JointState  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from lomanip_msgs.action import Execute  # noqa: E402
from lomanip_msgs.msg import ErrorCode, SceneObjects  # noqa: E402
from lomanip_msgs.srv import GetRGBDFrame, ResetScenario  # noqa: E402
from lomanip_sim import conversions as conv  # noqa: E402
from lomanip_sim import frames  # noqa: E402
from lomanip_sim.camera import CameraError, RGBDCamera  # noqa: E402
from lomanip_sim.camera_process import RGBDCameraProcess  # noqa: E402
from lomanip_sim.execution import Execution, execution_error  # noqa: E402
from lomanip_sim.robot_model import G1_JOINT_NAMES  # noqa: E402
from lomanip_sim.scenario import ScenarioError, load_scenario, parse_overrides_yaml, scenario_names  # noqa: E402
from lomanip_sim.simulator import Simulation  # noqa: E402
from lomanip_sim.trajectory import TrajectoryError  # noqa: E402

OPTICAL_FRAME = "scene_camera_optical"
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# REP 2003: sensor publishers use the system default (reliable) so best-effort and reliable
# subscribers can both connect; keep-last 2 keeps a slow subscriber from stalling the camera.
SENSOR = QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE)


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__("lomanip_sim")
        p = self._declare_parameters()
        self.params = load_scenario(p["scenario"], parse_overrides_yaml(p["scenario_overrides"]),
                                    p["scenario_file"] or None)
        self.scenario_file = p["scenario_file"] or None
        self.rtf_target = p["real_time_factor"]
        self.camera_period = 1.0 / p["camera_rate"]
        self.camera_process, self.camera_render_threads = bool(p["camera_process"]), int(p["camera_render_threads"])
        self.sim = Simulation(self.params)
        self._world_lock = threading.Lock()     # held by physics steps; taken by reset
        # Lock hand-off is not fair: a physics loop that is behind real time re-takes the lock at
        # once and can starve a reset for minutes on a loaded machine. A waiting reset sets this
        # flag and the physics loop stands aside until it is done.
        self._reset_waiting = threading.Event()
        self._waiters = 0                       # threads (reset, execute) waiting for the world lock
        self._waiters_lock = threading.Lock()
        self._camera_generation = 0             # bumped on reset so the render thread rebuilds
        self._snapshot_request: tuple[threading.Event, dict] | None = None
        self._stop = threading.Event()
        self._rtf = 0.0
        self._execution: Execution | None = None   # the running Execute goal's executor
        self._execution_interrupted = ""           # why a reset ended it
        self._execute_lock = threading.Lock()      # one Execute goal at a time

        self.pub_rgb = self.create_publisher(Image, "/lomanip/camera/rgb/image_raw", SENSOR)
        self.pub_depth = self.create_publisher(Image, "/lomanip/camera/depth/image_raw", SENSOR)
        self.pub_rgb_info = self.create_publisher(CameraInfo, "/lomanip/camera/rgb/camera_info", SENSOR)
        self.pub_depth_info = self.create_publisher(CameraInfo, "/lomanip/camera/depth/camera_info", SENSOR)
        self.pub_joints = self.create_publisher(JointState, "/joint_states", 10)
        self.pub_tf = self.create_publisher(TFMessage, "/tf", 10)
        self.pub_tf_static = self.create_publisher(TFMessage, "/tf_static", LATCHED)
        self.pub_scene = self.create_publisher(SceneObjects, "/lomanip/scene_objects", LATCHED)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)

        # /joint_states and /tf go out from the physics thread between its steps, not from executor
        # timers: dispatching 150 timer callbacks a second through rclpy's executor cost the physics
        # thread a third of its speed (real-time factor 0.41 against 0.58 with both at 10 Hz, session 25)
        self._state_topics = [(1.0 / p["joint_state_rate"], self._publish_joint_states),
                              (1.0 / p["tf_rate"], self._publish_tf)]
        timers = MutuallyExclusiveCallbackGroup()
        self.create_timer(1.0 / p["status_rate"], self._publish_status, callback_group=timers)
        services = ReentrantCallbackGroup()
        self.create_service(ResetScenario, "/lomanip/sim/reset", self._on_reset, callback_group=services)
        self.create_service(GetRGBDFrame, "/lomanip/sim/get_rgbd_frame", self._on_snapshot, callback_group=services)
        self._execute_server = ActionServer(self, Execute, "/lomanip/sim/execute", self._on_execute,
                                            goal_callback=lambda _g: GoalResponse.ACCEPT,
                                            cancel_callback=lambda _g: CancelResponse.ACCEPT,
                                            callback_group=ReentrantCallbackGroup())

        self._publish_scene()
        self._physics = threading.Thread(target=self._physics_loop, name="physics", daemon=True)
        self._render = threading.Thread(target=self._render_loop, name="render", daemon=True)
        self._physics.start()
        self._render.start()
        self.get_logger().info(f"scenario {self.params.name} ready: {len(self.sim.scene_objects())} objects, "
                               f"physics dt {self.sim.timestep * 1e3:.1f} ms at {self.rtf_target:g}x real time, "
                               f"camera {self.params.camera_width}x{self.params.camera_height} at {p['camera_rate']:g} Hz"
                               f" ({'worker process' if self.camera_process else 'thread'})")

    def _declare_parameters(self) -> dict:
        defaults = {"scenario": "s1_basket", "scenario_file": "", "scenario_overrides": "",
                    "real_time_factor": 1.0, "camera_rate": 5.0, "joint_state_rate": 100.0,
                    "tf_rate": 50.0, "status_rate": 1.0, "camera_process": True, "camera_render_threads": 1}
        descriptions = {"scenario": f"one of {', '.join(scenario_names())}",
                        "camera_process": "render the camera in a worker process (not on a thread beside physics)",
                        "camera_render_threads": "Mesa render threads of the camera worker (0 = Mesa's default)",
                        "scenario_overrides": "flat YAML mapping of scenario parameters",
                        "real_time_factor": "physics pacing, 0 = as fast as possible"}
        values = {}
        for name, default in defaults.items():
            desc = ParameterDescriptor(description=descriptions.get(name, ""), read_only=True)
            values[name] = self.declare_parameter(name, default, desc).value
        for rate in ("camera_rate", "joint_state_rate", "tf_rate", "status_rate"):
            if not values[rate] > 0:
                raise ScenarioError(f"parameter {rate} must be > 0, got {values[rate]}")
        if values["real_time_factor"] < 0:
            raise ScenarioError(f"parameter real_time_factor must be >= 0, got {values['real_time_factor']}")
        return values

    # --- physics -------------------------------------------------------------------------------
    def _physics_loop(self) -> None:
        chunk = max(1, round(0.002 / self.sim.timestep))   # step in 2 ms slices
        wall0, sim0 = time.perf_counter(), self.sim.time
        window_wall, window_sim = wall0, sim0
        due = [wall0] * len(self._state_topics)
        while not self._stop.is_set():
            if self._reset_waiting.is_set():
                time.sleep(0.001)
                continue
            with self._world_lock:
                self.sim.step(chunk)
                sim_t = self.sim.time
            now = time.perf_counter()
            for k, (period, publish) in enumerate(self._state_topics):
                if now >= due[k]:
                    due[k] = max(due[k] + period, now)  # no burst after a stall
                    try:
                        publish()
                    except Exception as exc:  # noqa: BLE001 - a failed publish (shutdown) must not stop physics
                        if self._stop.is_set() or not rclpy.ok():
                            return
                        self.get_logger().warning(f"state publish failed: {exc!r}")
            if now - window_wall >= 1.0:
                self._rtf = (sim_t - window_sim) / (now - window_wall)
                window_wall, window_sim = now, sim_t
            if self.rtf_target > 0:
                ahead = (sim_t - sim0) / self.rtf_target - (now - wall0)
                if ahead > 0:
                    time.sleep(ahead)
                elif ahead < -0.5:   # fell behind (e.g. after a reset): don't try to catch up
                    wall0, sim0 = now, sim_t

    # --- camera --------------------------------------------------------------------------------
    def _render_loop(self) -> None:
        camera, generation = None, -1
        next_frame = time.perf_counter()
        while not self._stop.is_set():
            if generation != self._camera_generation:
                if camera is not None:
                    camera.close()
                    camera = None
                with self._world_lock:  # the world of this generation (the camera is built outside the lock)
                    generation = self._camera_generation
                    model, name, params = self.sim.model, self.sim.world.camera_name, self.params
                try:
                    if self.camera_process:
                        camera = RGBDCameraProcess(model, name, params.camera_width, params.camera_height,
                                                   self.camera_render_threads)
                    else:
                        camera = RGBDCamera(model, name, params.camera_width, params.camera_height)
                except CameraError as exc:
                    self.get_logger().error(f"camera: {exc}; retrying in 5 s")
                    generation = -1
                    self._stop.wait(5.0)
                    continue
            request = self._snapshot_request
            now = time.perf_counter()
            if request is None and now < next_frame:
                time.sleep(min(next_frame - now, 0.005))
                continue
            snap = self.sim.snapshot()
            if generation != self._camera_generation:
                continue  # a reset since the camera was built: rebuild it first
            try:
                frame = camera.render(snap.qpos, snap.time)
            except CameraError as exc:  # a reset between the two checks (another model), or a dead worker
                self.get_logger().warning(f"camera: {exc}; rebuilding the camera")
                generation = -1
                continue
            if generation != self._camera_generation:
                continue  # the world was reset during the render: drop this frame
            stamp = self.get_clock().now().to_msg()
            msgs = self._camera_messages(stamp, frame)
            if request is not None:
                event, slot = request
                slot.update(msgs=msgs, pose=(frame.pose.position, frame.pose.quat_optical_wxyz))
                self._snapshot_request = None
                event.set()
            else:
                next_frame += self.camera_period
                if next_frame < now:
                    next_frame = now + self.camera_period
                if not self._publish_camera(msgs):
                    break
        if camera is not None:
            camera.close()

    def _publish_camera(self, msgs) -> bool:
        """Publish one frame; False once the ROS context is gone (Ctrl-C during a render)."""
        try:
            self.pub_rgb.publish(msgs[0])
            self.pub_depth.publish(msgs[1])
            self.pub_rgb_info.publish(msgs[2])
            self.pub_depth_info.publish(msgs[2])
        except Exception:  # rclpy raises RCLError/InvalidHandle after shutdown
            if not rclpy.ok(context=self.context):
                return False
            raise
        return True

    @staticmethod
    def _camera_messages(stamp, frame):
        k = frame.intrinsics
        info = conv.camera_info_msg(stamp, OPTICAL_FRAME, k.width, k.height, k.fx, k.fy, k.cx, k.cy)
        return conv.rgb_msg(stamp, OPTICAL_FRAME, frame.rgb), conv.depth_msg(stamp, OPTICAL_FRAME, frame.depth), info

    def _camera_optical_pose(self):
        """World pose of the fixed scene camera's optical frame (for /tf_static)."""
        model = self.sim.model
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, self.sim.world.camera_name)
        pos, R = frames.mujoco_camera_to_optical(data.cam_xpos[cam], data.cam_xmat[cam].reshape(3, 3))
        return pos, frames.matrix_to_quat(R)

    # --- state topics --------------------------------------------------------------------------
    def _publish_joint_states(self) -> None:
        q, v, tau = self.sim.joint_arrays()
        self.pub_joints.publish(conv.joint_state_msg(self.get_clock().now().to_msg(), G1_JOINT_NAMES, q, v, tau))

    def _publish_tf(self) -> None:
        stamp = self.get_clock().now().to_msg()
        pos, quat = self.sim.base_pose()
        transforms = [conv.transform_msg(stamp, "world", "pelvis", pos, quat)]
        for obj in self.sim.scene_objects():
            transforms.append(conv.transform_msg(stamp, "world", obj.id, obj.pos, obj.quat))
        self.pub_tf.publish(TFMessage(transforms=transforms))

    def _publish_scene(self, objects=None) -> None:
        stamp = self.get_clock().now().to_msg()
        objects = self.sim.scene_objects() if objects is None else objects
        self.pub_scene.publish(conv.scene_objects_msg(stamp, self.params.name, self.params.to_yaml(), objects))
        cam_pos, cam_quat = self._camera_optical_pose()
        self.pub_tf_static.publish(TFMessage(transforms=[
            conv.transform_msg(stamp, "world", OPTICAL_FRAME, cam_pos, cam_quat)]))

    def _publish_status(self) -> None:
        fallen = self.sim.has_fallen()
        status = DiagnosticStatus(level=DiagnosticStatus.ERROR if fallen else DiagnosticStatus.OK,
                                  name="lomanip_sim: physics", hardware_id="mujoco",
                                  message="robot has fallen" if fallen else "running")
        status.values = [KeyValue(key="real_time_factor", value=f"{self._rtf:.3f}"),
                         KeyValue(key="sim_time", value=f"{self.sim.time:.3f}"),
                         KeyValue(key="scenario", value=self.params.name),
                         KeyValue(key="fallen", value=str(fallen).lower())]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(msg)

    # --- services ------------------------------------------------------------------------------
    def _on_reset(self, request: ResetScenario.Request, response: ResetScenario.Response):
        name = request.scenario.name or self.params.name
        try:
            overrides = parse_overrides_yaml(request.scenario.overrides_yaml)
            params = load_scenario(name, overrides, self.scenario_file)
        except ScenarioError as exc:
            code = ErrorCode.UNKNOWN_SCENARIO if name not in scenario_names() else ErrorCode.INVALID_REQUEST
            response.error_code = ErrorCode(val=code, message=str(exc))
            self.get_logger().warning(f"reset refused: {exc}")
            return response
        try:
            with self._world():
                if self._execution is not None:   # a reset ends a running execution first
                    self._execution_interrupted = "interrupted by a scenario reset"
                    self._execution = None
                    self.sim.set_controller(None)
                self.sim.reset(params)
                self.params = params
                self._camera_generation += 1
                # one snapshot of the objects as placed, before physics steps again: the latched topic
                # (perception) and the response (planner) then carry the same poses, and the same
                # request gives the same scene on every run (the retargeting IK turns even 1e-11 m
                # differences into different keyframes)
                placed = self.sim.scene_objects()
        except Exception as exc:  # a world that fails to build must not kill the node
            response.error_code = ErrorCode(val=ErrorCode.INVALID_REQUEST, message=f"cannot build world: {exc}")
            self.get_logger().error(response.error_code.message)
            return response
        self._publish_scene(placed)
        response.scene = conv.scene_objects_msg(self.get_clock().now().to_msg(), params.name, params.to_yaml(), placed)
        response.error_code = ErrorCode(val=ErrorCode.SUCCESS, message="")
        self.get_logger().info(f"reset to {params.name} with {overrides or 'default parameters'}")
        return response

    def _on_snapshot(self, request: GetRGBDFrame.Request, response: GetRGBDFrame.Response):
        event, slot = threading.Event(), {}
        self._snapshot_request = (event, slot)
        if not event.wait(10.0):
            response.error_code = ErrorCode(val=ErrorCode.TIMEOUT, message="renderer did not answer in 10 s")
            return response
        response.rgb, response.depth, response.camera_info = slot["msgs"]
        pos, quat = slot["pose"]
        response.camera_pose = PoseStamped(pose=conv.pose_msg(pos, quat))
        response.camera_pose.header.stamp = response.rgb.header.stamp
        response.camera_pose.header.frame_id = "world"
        response.error_code = ErrorCode(val=ErrorCode.SUCCESS, message="")
        return response

    @contextlib.contextmanager
    def _world(self):
        """The world lock for a non-physics thread; the physics loop stands aside while it waits."""
        with self._waiters_lock:
            self._waiters += 1
            self._reset_waiting.set()
        try:
            with self._world_lock:
                yield
        finally:
            with self._waiters_lock:
                self._waiters -= 1
                if self._waiters == 0:
                    self._reset_waiting.clear()

    # --- Execute action ------------------------------------------------------------------------
    def _on_execute(self, goal_handle):
        """Check the trajectory, hand the robot to the WBC, report at ~10 Hz until done/cancelled."""
        result = Execute.Result()
        if not self._execute_lock.acquire(blocking=False):
            result.error_code = ErrorCode(val=ErrorCode.BUSY, message="another trajectory is being executed")
            goal_handle.abort()
            return result
        try:
            return self._execute(goal_handle, result)
        finally:
            self._execute_lock.release()

    def _execute(self, goal_handle, result):
        log = self.get_logger()
        try:
            traj = conv.trajectory_from_msg(goal_handle.request.trajectory)
            with self._world():   # checks against the CURRENT state, then the WBC takes over
                ex = Execution(self.sim, traj)
                ex.start()
                self._execution, self._execution_interrupted = ex, ""
        except Exception as exc:  # noqa: BLE001  (every failure becomes a coded result)
            err = execution_error(exc)
            if not isinstance(exc, TrajectoryError):
                log.error(f"execute: {exc!r}")
            result.error_code = ErrorCode(val=err.code, message=err.message)
            log.warning(f"execute refused: {err.message}")
            goal_handle.abort()
            return result
        log.info(f"executing {traj.scenario or 'a'} trajectory: {traj.n} points, {traj.duration:.2f} s")
        log.info(ex.wbc.reference_corrections())
        feedback = Execute.Feedback()
        try:
            while True:
                time.sleep(0.1)
                if self._execution is not ex:   # a reset took the robot away
                    ex.metrics = None
                    result.error_code = ErrorCode(val=ErrorCode.EXECUTION_FAILED, message=self._execution_interrupted)
                    goal_handle.abort()
                    return result
                if goal_handle.is_cancel_requested or self._stop.is_set():
                    with self._world():
                        ex.stop()
                        metrics = ex.finish(cancelled=True)
                    result.metrics = conv.execution_metrics_msg(metrics)
                    result.error_code = ErrorCode(val=ErrorCode.CANCELLED,
                                                  message=f"cancelled at t={ex.time:.2f} s; the standing controller holds")
                    goal_handle.canceled()
                    log.info(result.error_code.message)
                    return result
                st = ex.wbc.status
                feedback.time_from_start = float(min(ex.time, traj.duration))
                feedback.progress = ex.progress
                feedback.base_position_error = float(st.base_position_error)
                feedback.joint_error_rms = float(st.joint_error_rms)
                goal_handle.publish_feedback(feedback)
                if ex.done:
                    break
            with self._world():
                metrics = ex.finish()
                ex.stop()   # the standing controller holds the final posture
            result.metrics = conv.execution_metrics_msg(metrics)
            if metrics.fell:
                result.error_code = ErrorCode(val=ErrorCode.EXECUTION_FAILED,
                                              message=f"the robot fell at t={ex.time:.2f} s")
                goal_handle.abort()
            else:
                result.error_code = ErrorCode(val=ErrorCode.SUCCESS, message=metrics.task_success_detail)
                goal_handle.succeed()
            log.info(f"execution finished: task success {metrics.task_success}, fell {metrics.fell}, "
                     f"RTF {metrics.real_time_factor:.2f}; {metrics.task_success_detail}")
            if metrics.unplanned_contact:
                log.info(f"largest contact the plan did not have: {metrics.max_unplanned_contact_force:.0f} N, "
                         f"{metrics.unplanned_contact}")
            return result
        finally:
            with self._world():
                if self._execution is ex:
                    self._execution = None

    def shutdown(self) -> None:
        self._stop.set()
        self._physics.join(timeout=2.0)
        self._render.join(timeout=5.0)


def main(argv: list[str] | None = None) -> int:
    rclpy.init(args=argv if argv is not None else sys.argv)
    node = None
    try:
        node = SimNode()
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node)
        executor.spin()
    except (ScenarioError, ValueError) as exc:
        print(f"lomanip_sim: error: {exc}", file=sys.stderr, flush=True)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass   # Ctrl-C, also while the world is still being built
    finally:
        if node is not None:
            node.shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
