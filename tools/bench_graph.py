#!/usr/bin/env python3
"""Benchmark of the foundation graph: camera throughput to another process and physics pacing.

Starts the sim node as its own process (LOCALHOST discovery, a private ROS_DOMAIN_ID, lomanip's
Fast DDS profile), subscribes from THIS process to RGB, depth and joint states, and prints the
receive rates, image latency (header stamp -> receipt) and the real-time factor the node reports,
for each requested camera rate. Then the whole-body controller executing a small TO result through
the Execute action (the real-time factor the acceptance asks for) against the same run headless,
and the headless physics speed of the standing G1.

    .venv/bin/python tools/bench_graph.py [--seconds 15] [--camera-rates 15 30]
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(ROOT / "ros_ws/config/fastdds_localhost_shm.xml"))


def measure_graph(scenario: str, camera_rate: float, seconds: float) -> dict:
    import numpy as np
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image, JointState

    sim = subprocess.Popen([sys.executable, "-m", "lomanip_sim.sim_node", "--ros-args", "-p", f"scenario:={scenario}",
                            "-p", f"camera_rate:={camera_rate}"], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                           start_new_session=True)
    rclpy.init()
    node = rclpy.create_node("bench_graph")
    recv: dict[str, list[float]] = {"rgb": [], "depth": [], "joints": []}
    latency: list[float] = []
    rtf: list[float] = []

    def on_image(key):
        def cb(msg):
            now = node.get_clock().now().nanoseconds
            recv[key].append(time.monotonic())
            latency.append((now - (msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)) / 1e6)
        return cb

    node.create_subscription(Image, "/lomanip/camera/rgb/image_raw", on_image("rgb"), qos_profile_sensor_data)
    node.create_subscription(Image, "/lomanip/camera/depth/image_raw", on_image("depth"), qos_profile_sensor_data)
    node.create_subscription(JointState, "/joint_states", lambda m: recv["joints"].append(time.monotonic()), 10)
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: rtf.extend(
        float(kv.value) for s in m.status for kv in s.values if kv.key == "real_time_factor"), 10)
    try:
        deadline = time.monotonic() + 120
        while len(recv["rgb"]) < 5:
            if time.monotonic() > deadline or sim.poll() is not None:
                raise RuntimeError("sim node produced no images")
            rclpy.spin_once(node, timeout_sec=0.1)
        for v in recv.values():
            v.clear()
        latency.clear()
        rtf.clear()
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            rclpy.spin_once(node, timeout_sec=0.05)
        window = time.monotonic() - t0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        os.killpg(sim.pid, signal.SIGINT)
        sim.wait(20)
    return {"scenario": scenario, "camera_rate": camera_rate,
            **{f"{k}_hz": len(v) / window for k, v in recv.items()},
            "latency_ms_median": float(np.median(latency)) if latency else float("nan"),
            "latency_ms_p95": float(np.percentile(latency, 95)) if latency else float("nan"),
            "rtf_min": min(rtf[1:] or rtf or [float("nan")]),
            "rtf_mean": float(np.mean(rtf[1:] or rtf)) if rtf else float("nan")}


def measure_execution(camera_rate: float, case: str = "case_stand") -> dict:
    """Real-time factor of the whole-body controller executing a TO result: through the sim node's
    Execute action (camera streaming at ``camera_rate``, joint states and tf at their rates), and
    headless in this process (the controller and physics alone)."""
    import rclpy
    from builtin_interfaces.msg import Time
    from lomanip_msgs.action import Execute
    from rclpy.action import ActionClient

    from lomanip_sim.execution import Execution
    from lomanip_sim.simulator import make_simulation
    from lomanip_sim.trajectory import from_to_result
    from lomanip_to import conversions, fixtures, solver

    prob = fixtures.load_problem(case)
    res = solver.solve(prob).densify()
    headless = Execution(make_simulation("s1_basket"), from_to_result(res, prob.phases, scenario=case)).run()
    sim = subprocess.Popen([sys.executable, "-m", "lomanip_sim.sim_node", "--ros-args", "-p", "scenario:=s1_basket",
                            "-p", f"camera_rate:={camera_rate}"], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                           start_new_session=True)
    rclpy.init()
    node = rclpy.create_node("bench_graph_execute")
    ac = ActionClient(node, Execute, "/lomanip/sim/execute")
    try:
        deadline = time.monotonic() + 120
        while not ac.server_is_ready():
            if time.monotonic() > deadline or sim.poll() is not None:
                raise RuntimeError("no Execute action server")
            rclpy.spin_once(node, timeout_sec=0.1)
        time.sleep(3.0)  # the robot settles on its standing controller
        goal = Execute.Goal(trajectory=conversions.trajectory_msg(res, prob.phases, case, Time()))
        fut = ac.send_goal_async(goal)
        rclpy.spin_until_future_complete(node, fut, timeout_sec=30.0)
        rfut = fut.result().get_result_async()
        rclpy.spin_until_future_complete(node, rfut, timeout_sec=300.0)
        metrics = rfut.result().result.metrics
    finally:
        ac.destroy()
        node.destroy_node()
        rclpy.try_shutdown()
        os.killpg(sim.pid, signal.SIGINT)
        sim.wait(20)
    return {"case": case, "camera_rate": camera_rate, "duration_s": headless.duration,
            "rtf_graph": metrics.real_time_factor, "rtf_headless": headless.real_time_factor}


def measure_physics(scenario: str, sim_seconds: float) -> dict:
    from lomanip_sim.simulator import make_simulation

    sim = make_simulation(scenario)
    t0 = time.perf_counter()
    sim.run_for(sim_seconds)
    wall = time.perf_counter() - t0
    return {"scenario": scenario, "sim_s": sim_seconds, "wall_s": wall, "rtf": sim_seconds / wall,
            "pelvis_z": sim.pelvis_height(), "fallen": sim.has_fallen()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--camera-rates", type=float, nargs="+", default=[5.0, 15.0, 30.0])
    parser.add_argument("--scenario", default="s1_basket")
    parser.add_argument("--execute-camera-rates", type=float, nargs="+", default=[5.0, 15.0])
    args = parser.parse_args()
    print(f"nproc {os.cpu_count()}, ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, LOCALHOST discovery\n")
    print("Camera + physics through DDS (640x480 rgb8 + 32FC1, received by a separate process)")
    print(f"{'scenario':<11} {'asked Hz':>8} {'rgb Hz':>7} {'depth Hz':>8} {'joints Hz':>9} "
          f"{'lat ms p50':>10} {'lat ms p95':>10} {'RTF min':>7} {'RTF mean':>8}")
    for rate in args.camera_rates:
        r = measure_graph(args.scenario, rate, args.seconds)
        print(f"{r['scenario']:<11} {rate:>8.0f} {r['rgb_hz']:>7.1f} {r['depth_hz']:>8.1f} {r['joints_hz']:>9.1f} "
              f"{r['latency_ms_median']:>10.1f} {r['latency_ms_p95']:>10.1f} {r['rtf_min']:>7.3f} {r['rtf_mean']:>8.3f}",
              flush=True)
    print("\nWhole-body controller executing case_stand's TO result (500 Hz QP): through the sim node's Execute"
          " action (camera streaming, /joint_states 100 Hz, /tf 50 Hz) and headless")
    print(f"{'camera Hz':>9} {'sim s':>6} {'RTF graph':>9} {'RTF headless':>12}")
    for rate in args.execute_camera_rates:
        r = measure_execution(rate)
        print(f"{rate:>9.0f} {r['duration_s']:>6.1f} {r['rtf_graph']:>9.2f} {r['rtf_headless']:>12.2f}", flush=True)
    print("\nHeadless physics, standing controller every 2 ms step (no pacing, no rendering)")
    print(f"{'scenario':<11} {'sim s':>6} {'wall s':>7} {'RTF':>6} {'pelvis z':>8} {'fallen':>6}")
    for name in ("s1_basket", "s2_trolley"):
        r = measure_physics(name, 60.0)
        print(f"{name:<11} {r['sim_s']:>6.0f} {r['wall_s']:>7.2f} {r['rtf']:>6.1f} {r['pelvis_z']:>8.3f} "
              f"{str(r['fallen']):>6}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
