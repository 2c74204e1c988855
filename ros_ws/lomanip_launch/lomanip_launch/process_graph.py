"""Start, watch and stop the processes of the lomanip graph (the role `ros2 launch` plays).

No rclpy here: readiness is decided by a callable the caller passes in (the CLI asks the ROS graph).
Every node runs in its own process group so a terminal Ctrl-C reaches only the orchestrator, which
then shuts the nodes down in order: SIGINT, then SIGTERM, then SIGKILL.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, TextIO


class GraphError(RuntimeError):
    """A node failed to start or died while the graph was running."""


@dataclass
class NodeSpec:
    name: str                     # ROS node name, also the label in logs
    command: list[str]            # argv
    required: bool = True         # a required node dying stops the graph


@dataclass
class RunningNode:
    spec: NodeSpec
    process: subprocess.Popen
    log_path: Path
    started_at: float = field(default_factory=time.monotonic)

    @property
    def state(self) -> str:
        code = self.process.poll()
        return "running" if code is None else f"exited({code})"


#: /dev/shm names of Fast DDS: segments and their locks, ports, the ports' named semaphores
_FASTDDS_SHM_PREFIXES = ("fastrtps_", "fast_datasharing", "sem.fastrtps_")


def _shm_files() -> set[str]:
    try:
        return {p for p in os.listdir("/dev/shm") if p.startswith(_FASTDDS_SHM_PREFIXES)}
    except FileNotFoundError:
        return set()


def _shm_in_use() -> set[str]:
    """Names of /dev/shm files some live process still maps or holds open."""
    used: set[str] = set()
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/maps", encoding="utf-8", errors="replace") as maps:
                for line in maps:
                    if "/dev/shm/" in line:
                        used.add(line.rsplit("/dev/shm/", 1)[1].split()[0])
            for fd in os.listdir(f"/proc/{pid}/fd"):
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
                if target.startswith("/dev/shm/"):
                    used.add(target[len("/dev/shm/"):])
        except (OSError, IndexError):
            continue
    return used


def remove_stale_shm(min_age: float = 10.0, names: set[str] | None = None) -> list[str]:
    """Remove the Fast DDS shared-memory files no live process maps or holds open; their names.

    Why: a participant killed without its shutdown (SIGKILL, a crash, OOM) leaves its port file
    (fastrtps_port<N>), and so does one whose port another process was still writing to when it
    exited. The next participant that gets the same port number on that domain opens the old file
    and receives nothing over shared memory: in one test run every graph test after the
    orchestrator's kill tests failed on "no /lomanip/scene_objects received" (README, "Tests"). A
    live participant always maps its own port and segment, so a file nobody maps is stale. Files
    changed in the last ``min_age`` s are left alone: a participant starting right now may have
    created its file and not mapped it yet. ``names`` limits the removal to those files. Files of
    other users cannot be removed here (/dev/shm is sticky) and are left alone.
    """
    now = time.time()
    candidates = set()
    for name in _shm_files() if names is None else names:
        try:
            st = os.stat(os.path.join("/dev/shm", name))
        except OSError:
            continue
        if now - st.st_mtime >= min_age:
            candidates.add(name)
    if not candidates:
        return []
    removed = []
    for name in sorted(candidates - _shm_in_use()):
        try:
            os.unlink(os.path.join("/dev/shm", name))
            removed.append(name)
        except OSError:
            pass
    return removed


class ProcessGraph:
    """A set of node processes started together and stopped together."""

    def __init__(self, specs: list[NodeSpec], env: dict[str, str], log_dir: Path,
                 echo: TextIO | None = sys.stderr) -> None:
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise GraphError(f"duplicate node names: {names}")
        self.specs = specs
        self.env = env
        self.log_dir = log_dir
        self.echo = echo
        self.nodes: list[RunningNode] = []
        self._shm_before: set[str] | None = None

    def _say(self, text: str) -> None:
        if self.echo is not None:
            print(f"[lomanip] {text}", file=self.echo, flush=True)

    def watch_shm(self) -> None:
        """Remove stale Fast DDS files of earlier runs, then note which exist: the rest are ours.

        Call it before this process makes its own participant (the orchestrator's probe) so that
        shutdown also cleans what that participant leaves; ``start`` calls it if nobody did.
        """
        removed = remove_stale_shm()
        if removed:
            self._say(f"removed {len(removed)} stale Fast DDS shared-memory file(s) left by earlier runs")
        self._shm_before = _shm_files()

    def start(self) -> None:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        if self._shm_before is None:
            self.watch_shm()
        for spec in self.specs:
            log_path = self.log_dir / f"{spec.name}.log"
            log = open(log_path, "w", encoding="utf-8")  # noqa: SIM115 - closed by the child exiting
            proc = subprocess.Popen(spec.command, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, start_new_session=True)
            log.close()
            self.nodes.append(RunningNode(spec, proc, log_path))
            self._say(f"started {spec.name} (pid {proc.pid}), log {log_path}")

    def dead_nodes(self) -> list[RunningNode]:
        return [n for n in self.nodes if n.process.poll() is not None]

    def check(self) -> None:
        """Raise GraphError if a required node has exited."""
        for node in self.dead_nodes():
            if node.spec.required:
                tail = self.log_tail(node)
                raise GraphError(f"node {node.spec.name} exited with code {node.process.returncode}"
                                 + (f"; last log lines:\n{tail}" if tail else ""))

    def log_tail(self, node: RunningNode, lines: int = 8) -> str:
        try:
            text = node.log_path.read_text(encoding="utf-8", errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join("    " + line for line in text[-lines:])

    def wait_ready(self, is_ready: Callable[[], set[str]], timeout: float) -> None:
        """Block until is_ready() reports every node name, a node dies, or timeout passes."""
        deadline = time.monotonic() + timeout
        expected = {n.spec.name for n in self.nodes}
        reported: set[str] = set()
        while True:
            self.check()
            up = is_ready() & expected
            for name in sorted(up - reported):
                self._say(f"{name} is up")
            reported |= up
            if reported >= expected:
                return
            if time.monotonic() > deadline:
                missing = ", ".join(sorted(expected - reported))
                raise GraphError(f"timed out after {timeout:.0f} s waiting for: {missing}")
            time.sleep(0.2)

    def status_lines(self) -> list[str]:
        return [f"{n.spec.name:<24} pid {n.process.pid:<8} {n.state}" for n in self.nodes]

    def shutdown(self, grace: float = 8.0) -> None:
        """Stop every node (reverse start order), then remove Fast DDS shm files they left."""
        for sig, wait in ((signal.SIGINT, grace), (signal.SIGTERM, 3.0), (signal.SIGKILL, 2.0)):
            alive = [n for n in reversed(self.nodes) if n.process.poll() is None]
            if not alive:
                break
            for node in alive:
                try:
                    os.killpg(node.process.pid, sig)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + wait
            for node in alive:
                try:
                    node.process.wait(timeout=max(0.0, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    if sig == signal.SIGKILL:
                        self._say(f"{node.spec.name} did not exit")
            if sig != signal.SIGINT:
                stubborn = [n.spec.name for n in alive]
                self._say(f"sent {signal.Signals(sig).name} to {', '.join(stubborn)}")
        self._cleanup_shm()

    def _cleanup_shm(self, settle: float = 2.0) -> None:
        """Remove the files created since ``watch_shm`` that no live process maps any more.

        Every node has exited, so what they made is stale; a participant elsewhere on the domain
        may still map a node's segment for a moment after it left (CI once found one left behind
        after a clean Ctrl-C), so files still in use are retried for ``settle`` seconds.
        """
        before = self._shm_before or set()
        removed: list[str] = []
        deadline = time.monotonic() + settle
        while True:
            removed += remove_stale_shm(min_age=0.0, names=_shm_files() - before)
            if not (_shm_files() - before) or time.monotonic() >= deadline:
                break
            time.sleep(0.2)
        if removed:
            self._say(f"removed {len(removed)} stale Fast DDS shared-memory file(s)")