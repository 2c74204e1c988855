"""lomanip_to node: the whole-body trajectory optimisation as a ROS 2 service.

  /lomanip/to/optimize                  lomanip_msgs/srv/OptimizeTrajectory
  /lomanip/trajectory                   lomanip_msgs/WholeBodyTrajectory (reliable, transient local)
  /lomanip/trajectory/joint_trajectory  trajectory_msgs/JointTrajectory (29 G1 joints), same QoS
  /lomanip/trajectory/base_trajectory   trajectory_msgs/MultiDOFJointTrajectory ("floating_base"), same QoS
  /lomanip/to/cancel                    std_srvs/Trigger: stops the running solve (its request gets
                                        CANCELLED); only with isolate_solver (the default)
  /lomanip/to/progress                  lomanip_msgs/SolverStatistics, during a solve (<= ~5 Hz):
                                        iterations so far, cost = objective, max_dynamics_violation =
                                        max constraint violation of the iterate, solve_time = elapsed
                                        s, status_message = stage (e.g. "subtask 1 (3.0-11.4 s) final")

Invalid input is answered with its error code before any solve. The solve runs in a worker process
(parameter ``isolate_solver``, default true) that is killed when it overruns the problem's time
limit by solver_process.hard_deadline: the request then gets TIMEOUT, never a hang. Only a solve that converged AND
passed the physical-consistency checks is returned as a trajectory and published; a failed solve
returns TO_NOT_CONVERGED with the reason and the solver statistics, and an empty trajectory. One
solve at a time: a request while another runs is answered BUSY.
"""
from __future__ import annotations

import sys
import threading
import time

import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, MultiDOFJointTrajectory

from lomanip_msgs.msg import ErrorCode, SolverStatistics, WholeBodyTrajectory
from lomanip_msgs.srv import OptimizeTrajectory

from . import conversions as conv
from .problem import TO_NOT_CONVERGED, ProblemError

#: progress messages are rate-limited to this period (s); a log line every LOG_EVERY iterations
PROGRESS_PERIOD = 0.2
LOG_EVERY = 25

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TONode(Node):
    def __init__(self) -> None:
        super().__init__("lomanip_to")
        self.threads = int(self.declare_parameter("threads", 2).value)
        # solve in a worker process that is killed if an ipopt iteration overruns the time limit
        # (solver_process.hard_deadline); False: in this process, no hard deadline
        self.isolate_solver = bool(self.declare_parameter("isolate_solver", True).value)
        # where each accepted request's problem is pickled before its solve ("" = nowhere), so that a
        # solve that failed in the graph can be re-run offline: solver.solve(pickle.load(f))
        self.problem_dir = str(self.declare_parameter("problem_dir", "").value)
        self._requests = 0
        from .solver import default_model

        t0 = time.perf_counter()
        self.model = default_model()
        self.joint_names = list(self.model.joint_names)
        self.get_logger().info(f"G1 model loaded in {time.perf_counter() - t0:.1f} s "
                               f"({len(self.joint_names)} joints)")
        self._busy = threading.Lock()
        self.worker = None
        if self.isolate_solver:
            from .solver_process import SolverProcess

            self.worker = SolverProcess(threads=self.threads)
        self.pub_traj = self.create_publisher(WholeBodyTrajectory, "/lomanip/trajectory", LATCHED)
        self.pub_joint = self.create_publisher(JointTrajectory, "/lomanip/trajectory/joint_trajectory", LATCHED)
        self.pub_base = self.create_publisher(MultiDOFJointTrajectory, "/lomanip/trajectory/base_trajectory", LATCHED)
        self.pub_progress = self.create_publisher(SolverStatistics, "/lomanip/to/progress", 10)
        self._cancel = threading.Event()
        self.create_service(OptimizeTrajectory, "/lomanip/to/optimize", self._on_optimize,
                            callback_group=ReentrantCallbackGroup())
        self.create_service(Trigger, "/lomanip/to/cancel", self._on_cancel, callback_group=ReentrantCallbackGroup())

    def _save_problem(self, problem) -> None:
        if not self.problem_dir:
            return
        import pickle

        self._requests += 1

        def write(path: str) -> None:
            with open(path, "wb") as f:
                pickle.dump(problem, f)

        self._save_request_file("problem", f"to_problem_{self._requests}.pkl", write)

    def _save_result(self, result) -> None:
        """to_result_<n>.npz beside to_problem_<n>.pkl: the solver's own result, converged or not, so
        a run can be replayed under physics (tools/exec_trace.py runs/<run>)."""
        if self.problem_dir:
            self._save_request_file("result", f"to_result_{self._requests}.npz", result.save)

    def _save_request_file(self, what: str, name: str, write) -> None:
        """``write(path)`` into problem_dir; a full disk must not stop the solve, so an OSError is logged."""
        import os

        path = os.path.join(self.problem_dir, name)
        try:
            os.makedirs(self.problem_dir, exist_ok=True)
            write(path)
            self.get_logger().info(f"{what} saved to {path}")
        except OSError as exc:
            self.get_logger().warning(f"could not save the {what} to {path}: {exc}")

    def _on_cancel(self, request, response):
        if self.worker is None:
            response.success, response.message = False, "isolate_solver is false: a solve cannot be stopped"
        elif not self._busy.locked():
            response.success, response.message = False, "no optimisation is running"
        else:
            self._cancel.set()
            response.success, response.message = True, "stopping the running optimisation"
            self.get_logger().info("cancel requested")
        return response

    def _on_optimize(self, request, response):
        if not self._busy.acquire(blocking=False):
            response.error_code = ErrorCode(val=ErrorCode.BUSY, message="another optimisation is running")
            return response
        try:
            return self._optimize(request, response)
        finally:
            self._busy.release()

    def _optimize(self, request, response):
        from .problem import validate_problem
        from .solver import solve

        log = self.get_logger()
        try:
            problem = conv.problem_from_request(request, self.joint_names)
            validate_problem(problem, self.model)
        except ProblemError as exc:
            response.error_code = ErrorCode(val=exc.code, message=f"{exc.where}: {exc.message}" if exc.where else exc.message)
            log.warning(f"request refused: {response.error_code.message}")
            return response
        log.info(f"optimising {problem.name or 'trajectory'}: {len(problem.keyframes)} keyframes, "
                 f"{len(problem.phases)} phases, {problem.duration:.1f} s")
        self._save_problem(problem)
        try:
            if self.worker is not None:
                self._cancel.clear()
                result = self.worker.solve(problem, progress=self._progress_sink(), cancel=self._cancel)
            else:
                result = solve(problem, self.model, threads=self.threads, progress=self._progress_sink())
        except ProblemError as exc:   # includes solver_process.SolveAborted (TIMEOUT, CANCELLED)
            response.error_code = ErrorCode(val=exc.code, message=exc.message)
            log.error(f"optimisation stopped: {exc.message}")
            return response
        self._save_result(result)
        stats = result.stats
        response.trajectory.solver_statistics = conv.statistics_msg(stats)
        for stage in stats.stages:  # one line per homotopy stage of each segment: where the time went
            rows = f", {stage['rows']} rows ({stage['screened_rows']} screened out)" if "screened_rows" in stage else ""
            log.info(f"  {stage['stage'].strip()}: {stage['status']}, {stage['iterations']} iterations, "
                     f"{stage['time']:.1f} s{rows}")
        log.info(f"{stats.status_message()}; {stats.iterations} iterations, build {stats.build_time:.1f} s, "
                 f"solve {stats.solve_time:.1f} s")
        if not result.success:
            # name each failed check with its value and where it occurs, e.g.
            # "torque_limits 1.3 at right_wrist_pitch_joint t=2.10"
            failed = [f"{name} {c.get('value', float('nan')):.3g} at {c.get('where', '?')}"
                      for name, c in stats.checks.items() if not c.get("ok", False)]
            reason = stats.status_message() + (f"; failed checks: {', '.join(failed)}" if failed else "")
            response.error_code = ErrorCode(val=TO_NOT_CONVERGED, message=reason)
            return response
        stamp = self.get_clock().now().to_msg()
        response.trajectory = conv.trajectory_msg(result, problem.phases, problem.name, stamp)
        response.error_code = ErrorCode(val=ErrorCode.SUCCESS, message=stats.status_message())
        self.pub_traj.publish(response.trajectory)
        self.pub_joint.publish(response.trajectory.joint_trajectory)
        self.pub_base.publish(response.trajectory.base_trajectory)
        return response


    def _progress_sink(self):
        """Per-iteration callback of one solve: publishes at most every PROGRESS_PERIOD s (the
        first iteration always), logs every LOG_EVERY iterations.  Runs in the solving thread."""
        last = [-1e9]
        log = self.get_logger()

        def sink(p) -> None:
            if p.iteration % LOG_EVERY == 0:
                log.info(p.text())
            if p.elapsed - last[0] < PROGRESS_PERIOD:
                return
            last[0] = p.elapsed
            self.pub_progress.publish(progress_msg(p))

        return sink


def progress_msg(p) -> SolverStatistics:
    """lomanip_msgs/SolverStatistics of an in-progress solve (converged stays False)."""
    return SolverStatistics(solver="ipopt (in progress)", converged=False, iterations=int(p.iteration),
                            solve_time=float(p.elapsed), cost=float(p.objective),
                            max_dynamics_violation=float(p.constraint_violation), status_message=p.stage)


def main(argv: list[str] | None = None) -> int:
    rclpy.init(args=argv if argv is not None else sys.argv)
    node = None
    try:
        node = TONode()
        executor = MultiThreadedExecutor(num_threads=2)
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            if node.worker is not None:
                node.worker.close()
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
