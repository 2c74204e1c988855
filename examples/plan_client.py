#!/usr/bin/env python3
"""Call lomanip's plan service from your own rclpy code and receive the trajectory on its topic.

Written only against the public interface (lomanip_msgs + standard messages); it imports nothing
from lomanip's Python packages. With the graph running (`lomanip up --scenario s2_trolley`):

    python examples/plan_client.py --scenario s2_trolley "pick up the box from the table"
"""
import argparse
import sys

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from lomanip_msgs.msg import ErrorCode, PlacementGoal, WholeBodyTrajectory
from lomanip_msgs.srv import PlanTask


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("prompts", nargs="+", help="ordered subtask prompts")
    parser.add_argument("--scenario", default="", help="reset the simulator to this scenario first")
    parser.add_argument("--place", nargs=4, metavar=("OBJECT", "X", "Y", "Z"), help="one placement goal")
    parser.add_argument("--timeout", type=float, default=1800.0, help="s to wait for the plan")
    args = parser.parse_args()

    rclpy.init()
    node = rclpy.create_node("my_plan_client")
    received = []
    # /lomanip/trajectory is latched (reliable + transient local): a late subscriber still gets the last plan.
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(WholeBodyTrajectory, "/lomanip/trajectory", received.append, latched)
    client = node.create_client(PlanTask, "/lomanip/plan")
    if not client.wait_for_service(timeout_sec=30.0):
        print("error: /lomanip/plan is not available; start the graph with `lomanip up`", file=sys.stderr)
        return 1

    request = PlanTask.Request(prompts=args.prompts)
    request.scenario.name = args.scenario
    if args.place:
        goal = PlacementGoal(object_id=args.place[0])
        goal.position.x, goal.position.y, goal.position.z = (float(v) for v in args.place[1:])
        request.placement_goals = [goal]
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=args.timeout)
    response = future.result()
    if response is None:
        print(f"error: no answer within {args.timeout:.0f} s", file=sys.stderr)
        return 1
    print("stages:", ", ".join(f"{t.stage} {t.seconds:.1f} s" for t in response.timings))
    if response.error_code.val != ErrorCode.SUCCESS:
        print(f"plan failed ({response.error_code.val}): {response.error_code.message}", file=sys.stderr)
        return 1

    # The same trajectory also arrives on the topic, stamped with the planned start time.
    while not received:
        rclpy.spin_once(node, timeout_sec=0.5)
    traj = received[-1]
    points = traj.joint_trajectory.points
    end = points[-1].time_from_start
    print(f"trajectory: {len(points)} points over {end.sec + end.nanosec * 1e-9:.2f} s, "
          f"{len(traj.joint_trajectory.joint_names)} joints, objects {[o.object_id for o in traj.object_trajectories]}, "
          f"TO {traj.solver_statistics.iterations} iterations")
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
