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
