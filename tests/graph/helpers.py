"""Shared helpers for graph tests: start lomanip processes with the test environment."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def graph_env() -> dict[str, str]:
    env = dict(os.environ)  # conftest set LOCALHOST discovery and our own ROS_DOMAIN_ID
    paths = [str(ROOT / p) for p in ("src/lomanip_sim", "src/lomanip_to", "src/lomanip_perception",
                                     "src/lomanip_planner", "ros_ws/lomanip_launch")]
    env["PYTHONPATH"] = os.pathsep.join(paths + [env.get("PYTHONPATH", "")])
    return env


@contextmanager
def ros_process(args: list[str], log_path: Path):
    """Run `python -m ...` as its own process group; SIGINT it (then kill) on exit."""
    log = open(log_path, "w")
    proc = subprocess.Popen([sys.executable, *args], env=graph_env(), stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)
        log.close()


def wait_for(predicate, timeout: float, what: str, spin=None, proc=None, log_path=None):
    deadline = time.monotonic() + timeout
    while not predicate():
        if proc is not None and proc.poll() is not None:
            text = Path(log_path).read_text() if log_path else ""
            raise AssertionError(f"process exited ({proc.returncode}) while waiting for {what}:\n{text[-3000:]}")
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        if spin is not None:
            spin()
        else:
            time.sleep(0.05)


def wait_for_service(node, cli, timeout: float = 60.0, settle: float = 1.0, proc=None, log_path=None):
    """Wait until ``cli`` sees its server, then spin ``settle`` s more so the server can match our
    response reader too (see call_idempotent for the race this narrows)."""
    import rclpy

    spin = lambda: rclpy.spin_once(node, timeout_sec=0.05)  # noqa: E731
    wait_for(cli.service_is_ready, timeout, f"service {cli.srv_name}", spin=spin, proc=proc, log_path=log_path)
    end = time.monotonic() + settle
    while time.monotonic() < end:
        spin()


def call_idempotent(node, cli, request, timeout: float = 60.0, attempt: float = 15.0):
    """Call a service whose request may safely be repeated; re-send if no answer in ``attempt`` s.

    Why: right after discovery, Fast DDS can report a service ready before the server has matched
    the client's response reader; the server then drops that first response (a known rmw_fastrtps
    race that shows under load, e.g. on a busy 2-core CI machine). A second request goes through.
    """
    import rclpy

    wait_for_service(node, cli)
    deadline = time.monotonic() + timeout
    while True:
        future = cli.call_async(request)
        rclpy.spin_until_future_complete(node, future, timeout_sec=min(attempt, max(0.1, deadline - time.monotonic())))
        if future.done():
            return future.result()
        cli.remove_pending_request(future)
        if time.monotonic() >= deadline:
            raise AssertionError(f"{cli.srv_name} did not answer in {timeout} s")
