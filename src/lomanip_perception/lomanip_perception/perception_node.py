"""lomanip_perception node: prompts (+ scene RGB-D) -> 3D contacts per subtask (paper Sec. III-A).

Service:
  /lomanip/perception/extract_contacts   lomanip_msgs/srv/ExtractContacts
      prompts in; optional rgb/depth/camera_info/camera_pose (empty rgb = ask the simulator for a
      frame via /lomanip/sim/get_rgbd_frame); contacts per subtask, human poses and stage timings out.
Subscribes:
  /lomanip/scene_objects                 lomanip_msgs/SceneObjects (latched)
Publishes (latched, so late subscribers get the last answer):
  /lomanip/contacts                      lomanip_msgs/ContactSet
  /lomanip/perception/contact_markers    visualization_msgs/MarkerArray (contact spheres, normals, labels;
                                         RViz / Foxglove, frame 'world')

Model backends come from config/perception.yaml (parameter config_file); the default backends are
the 'synthetic' offline stand-ins (see lomanip_perception.synthetic). Any failure answers with an
error code and a one-line message naming the subtask; the node keeps serving. At start-up the node
logs one line per role naming the backend that serves it (and 'SYNTHETIC' for the offline stand-ins)
and its start-up time; a backend that cannot load (the paper's models without local weights) stops
the node with exit code 2 and one line.
"""
from __future__ import annotations

import sys
import threading
import time

_T_START = time.perf_counter()  # start-up time is measured from here (before rclpy, mujoco, open3d)

import lomanip_sim  # noqa: F401  (headless GL backend before mujoco)
import rclpy  # noqa: E402
import yaml  # noqa: E402
from rcl_interfaces.msg import ParameterDescriptor  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup  # noqa: E402
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from lomanip_msgs.msg import ContactSet, ErrorCode, SceneObjects  # noqa: E402
from lomanip_msgs.srv import ExtractContacts, GetRGBDFrame  # noqa: E402

from . import conversions as conv  # noqa: E402
from .config import build_from_config, default_config_path, load_config  # noqa: E402
from .errors import FAILURE, NOT_READY, TIMEOUT, PerceptionError  # noqa: E402
from .pipeline import PerceptionPipeline, SceneInput  # noqa: E402

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class PerceptionNode(Node):
    def __init__(self) -> None:
        super().__init__("lomanip_perception")
        p = self._declare_parameters()
        overrides = yaml.safe_load(p["config_overrides"]) if p["config_overrides"] else {}
        if overrides is not None and not isinstance(overrides, dict):
            raise PerceptionError("INVALID_REQUEST", "config_overrides must be a YAML mapping")
        if p["transfer_method"]:
            overrides = {**(overrides or {}), "transfer": {**(overrides or {}).get("transfer", {}),
                                                           "method": p["transfer_method"]}}  # fmt: skip
        cfg_path = p["config_file"] or str(default_config_path())
        cfg = load_config(cfg_path, overrides)
        models, transfer, seed = build_from_config(cfg)
        self.pipeline = PerceptionPipeline(models, transfer, seed, logger=None)
        self.scene_timeout = p["scene_timeout"]
        self.frame_timeout = p["frame_timeout"]
        self._scene: SceneObjects | None = None
        self._scene_event = threading.Event()

        io = ReentrantCallbackGroup()
        self.create_subscription(SceneObjects, "/lomanip/scene_objects", self._on_scene, LATCHED, callback_group=io)
        self.frame_client = self.create_client(GetRGBDFrame, "/lomanip/sim/get_rgbd_frame", callback_group=io)
        self.pub_contacts = self.create_publisher(ContactSet, "/lomanip/contacts", LATCHED)
        self.pub_markers = self.create_publisher(MarkerArray, "/lomanip/perception/contact_markers", LATCHED)
        self.create_service(ExtractContacts, "/lomanip/perception/extract_contacts", self._on_extract,
                            callback_group=MutuallyExclusiveCallbackGroup())  # fmt: skip
        names, described = models.names(), models.describe()
        for role in names:
            what = ("SYNTHETIC offline stand-in (reads the synthetic demonstration's ground truth, not a model)"
                    if names[role] == "synthetic" else described[role])
            self.get_logger().info(f"role {role:<15} backend {names[role]}: {what}")
        self.get_logger().info(
            f"ready in {time.perf_counter() - _T_START:.2f} s (config {cfg_path}): transfer {transfer.method} "
            f"({transfer.iterations} iterations, top-{transfer.top_n}, "
            f"{'similarity' if transfer.similarity else 'rigid'} SVD)")  # fmt: skip

    def _declare_parameters(self) -> dict:
        defaults = {"config_file": "", "config_overrides": "", "transfer_method": "", "scene_timeout": 5.0,
                    "frame_timeout": 10.0}
        descriptions = {"config_file": "perception YAML (empty = the package's config/perception.yaml)",
                        "config_overrides": "YAML mapping merged over the config file, e.g. "
                                            "'{models: {matcher: {params: {outlier_rate: 0.2}}}}'",
                        "transfer_method": "override: geometry_aware | geometry_unaware",
                        "scene_timeout": "s to wait for /lomanip/scene_objects",
                        "frame_timeout": "s to wait for the simulator's RGB-D frame"}
        return {n: self.declare_parameter(n, d, ParameterDescriptor(description=descriptions[n], read_only=True)).value
                for n, d in defaults.items()}  # fmt: skip

    def _on_scene(self, msg: SceneObjects) -> None:
        self._scene = msg
        self._scene_event.set()

    def _scene_frame(self, request):
        if len(request.rgb.data) or len(request.depth.data):
            return conv.scene_image_from_msgs(request.rgb, request.depth, request.camera_info, request.camera_pose)
        if not self.frame_client.wait_for_service(timeout_sec=min(self.frame_timeout, 5.0)):
            raise PerceptionError(NOT_READY, "no RGB-D frame in the request and /lomanip/sim/get_rgbd_frame is not available")
        done = threading.Event()
        future = self.frame_client.call_async(GetRGBDFrame.Request())
        future.add_done_callback(lambda _: done.set())
        if not done.wait(self.frame_timeout):
            future.cancel()
            raise PerceptionError(TIMEOUT, f"the simulator did not send an RGB-D frame in {self.frame_timeout:g} s")
        res = future.result()
        if res.error_code.val != ErrorCode.SUCCESS:
            raise PerceptionError(NOT_READY, f"simulator frame request failed: {res.error_code.message}")
        return conv.scene_image_from_msgs(res.rgb, res.depth, res.camera_info, res.camera_pose.pose)

    def _on_extract(self, request: ExtractContacts.Request, response: ExtractContacts.Response):
        t0 = time.perf_counter()
        try:
            if not request.prompts:
                self.pipeline.parse([], SceneInput(None, []))  # raises INVALID_REQUEST: empty prompt list
            if not self._scene_event.wait(self.scene_timeout):
                raise PerceptionError(NOT_READY, f"no /lomanip/scene_objects received in {self.scene_timeout:g} s")
            objects = conv.scene_objects_from_msg(self._scene)
            scene = SceneInput(None, objects)
            self.pipeline.parse(list(request.prompts), scene)  # fail fast on unknown objects
            t1 = time.perf_counter()
            scene.image = self._scene_frame(request)
            t_frame = time.perf_counter() - t1
            results = self.pipeline.run(list(request.prompts), scene)
        except PerceptionError as exc:
            response.error_code = conv.error_msg(exc.code, exc.message)
            self.get_logger().warning(f"extract_contacts refused: [{exc.code}] {exc.message}")
            return response
        except Exception as exc:  # never let a request kill the node
            response.error_code = conv.error_msg(FAILURE, f"internal error: {type(exc).__name__}: {exc}")
            self.get_logger().error(f"extract_contacts failed: {exc!r}")
            return response
        stamp = self.get_clock().now().to_msg()
        response.contacts = conv.contact_set_msg(results, stamp)
        response.human_poses = conv.human_pose_msgs(results, stamp)
        response.timings = conv.timing_msgs(results, {"scene_frame": t_frame, "total": time.perf_counter() - t0})
        response.error_code = conv.error_msg("SUCCESS", "")
        self.pub_contacts.publish(response.contacts)
        self.pub_markers.publish(conv.markers_msg(results, stamp))
        n = sum(len(s.contacts) for s in response.contacts.subtasks)
        self.get_logger().info(f"extract_contacts: {len(results)} subtasks, {n} contacts in "
                               f"{time.perf_counter() - t0:.1f} s")  # fmt: skip
        return response


def main(argv: list[str] | None = None) -> int:
    try:
        rclpy.init(args=argv if argv is not None else sys.argv)
    except Exception as exc:  # rcl's own argument errors (e.g. a -p value that is not valid YAML)
        print(f"lomanip_perception: error: bad ROS arguments: {str(exc).splitlines()[0]}", file=sys.stderr, flush=True)
        return 2
    try:
        node = PerceptionNode()
    except (PerceptionError, ValueError, yaml.YAMLError) as exc:
        print(f"lomanip_perception: error: {exc}", file=sys.stderr, flush=True)
        rclpy.try_shutdown()
        return 2
    executor = MultiThreadedExecutor(num_threads=3)
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
