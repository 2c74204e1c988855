"""The orchestrator's process handling, with plain Python processes standing in for nodes."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from lomanip_launch.process_graph import GraphError, NodeSpec, ProcessGraph

SLEEPER = [sys.executable, "-c", "import time\nwhile True: time.sleep(0.1)"]
# Ignores SIGINT, like a hung node: the graph must escalate to SIGTERM.
STUBBORN = [sys.executable, "-c",
            "import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\nwhile True: time.sleep(0.1)"]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead for our purposes.
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split()[2] != "Z"


def test_a_dying_node_is_reported_and_the_rest_are_stopped(tmp_path):
    graph = ProcessGraph([NodeSpec("a", SLEEPER), NodeSpec("b", STUBBORN)], dict(os.environ), tmp_path, echo=None)
    graph.start()
    try:
        graph.wait_ready(lambda: {"a", "b"}, timeout=5)
        victim = graph.nodes[0].process
        victim.send_signal(signal.SIGKILL)
        victim.wait(5)
        with pytest.raises(GraphError, match="node a exited"):
            graph.check()
    finally:
        graph.shutdown(grace=1.0)
    assert not any(_alive(n.process.pid) for n in graph.nodes)


def test_wait_ready_times_out_with_the_missing_names(tmp_path):
    graph = ProcessGraph([NodeSpec("a", SLEEPER), NodeSpec("b", SLEEPER)], dict(os.environ), tmp_path, echo=None)
    graph.start()
    try:
        t0 = time.monotonic()
        with pytest.raises(GraphError, match="waiting for: b"):
            graph.wait_ready(lambda: {"a"}, timeout=1.0)
        assert time.monotonic() - t0 < 3
    finally:
        graph.shutdown(grace=1.0)


def test_duplicate_names_are_refused(tmp_path):
    with pytest.raises(GraphError, match="duplicate"):
        ProcessGraph([NodeSpec("a", SLEEPER), NodeSpec("a", SLEEPER)], {}, tmp_path)


def test_stale_shared_memory_is_removed_and_mapped_files_are_kept():
    """A Fast DDS port file nobody maps is stale (its owner died) and goes; a mapped one stays."""
    import mmap

    from lomanip_launch.process_graph import remove_stale_shm

    stale = f"/dev/shm/fastrtps_port_lomanip_test_stale_{os.getpid()}"
    stale_sem = f"/dev/shm/sem.fastrtps_port_lomanip_test_stale_{os.getpid()}_mutex"
    live = f"/dev/shm/fastrtps_port_lomanip_test_live_{os.getpid()}"
    fresh = f"/dev/shm/fastrtps_port_lomanip_test_fresh_{os.getpid()}"
    for path in (stale, stale_sem, live, fresh):
        with open(path, "wb") as f:
            f.write(b"\0" * 4096)
    old = time.time() - 60.0
    for path in (stale, stale_sem, live):
        os.utime(path, (old, old))
    with open(live, "r+b") as f, mmap.mmap(f.fileno(), 4096) as _mapped:
        removed = remove_stale_shm(min_age=10.0)
        assert os.path.basename(stale) in removed and os.path.basename(stale_sem) in removed
        assert not os.path.exists(stale) and not os.path.exists(stale_sem)
        assert os.path.exists(live)
        assert os.path.exists(fresh)  # just created: perhaps a participant that has not mapped it yet
    os.unlink(live)
    os.unlink(fresh)


def test_shutdown_removes_a_file_once_its_last_reader_lets_go(tmp_path):
    """A Fast DDS file made during the graph's run that another process still maps at shutdown
    goes once that process lets go (within the settle time); files from before ``watch_shm`` stay."""
    import mmap

    graph = ProcessGraph([NodeSpec("a", SLEEPER)], dict(os.environ), tmp_path, echo=None)
    before = f"/dev/shm/fastrtps_lomanip_test_before_{os.getpid()}"
    ours = f"/dev/shm/fastrtps_lomanip_test_ours_{os.getpid()}"
    try:
        with open(before, "wb") as f:
            f.write(b"\0" * 4096)
        graph.watch_shm()
        with open(ours, "wb") as f:
            f.write(b"\0" * 4096)
        reader = subprocess.Popen([sys.executable, "-c",
                                   "import mmap, time\n"
                                   f"f = open({ours!r}, 'r+b'); m = mmap.mmap(f.fileno(), 4096)\n"
                                   "print('mapped', flush=True); time.sleep(0.8)"],
                                  stdout=subprocess.PIPE, text=True)
        assert reader.stdout.readline().strip() == "mapped"
        graph.start()
        graph.shutdown(grace=2.0)   # the node stops at once; the reader holds `ours` 0.8 s longer
        assert reader.wait(timeout=10) == 0
        assert not os.path.exists(ours)
        assert os.path.exists(before)
    finally:
        for path in (before, ours):
            if os.path.exists(path):
                os.unlink(path)
