"""The TO in a killable worker process: results and progress come back, a deadline or a cancel
stops the worker within a poll period, and the next solve gets a fresh worker."""
import threading
import time

import pytest

from lomanip_to.fixtures import load_problem
from lomanip_to.problem import TIMEOUT
from lomanip_to.solver_process import CANCELLED, SolveAborted, SolverProcess, hard_deadline


@pytest.fixture(scope="module")
def worker():
    w = SolverProcess(threads=1)
    yield w
    w.close()


def test_hard_deadline_leaves_the_solver_its_own_time_limit_first():
    assert hard_deadline(300.0) == pytest.approx(375.0)
    assert hard_deadline(10.0) == pytest.approx(70.0)


def test_a_solve_in_the_worker_returns_the_result_and_reports_progress(worker, g1):
    seen = []
    res = worker.solve(load_problem("case_stand", model=g1), progress=seen.append)
    assert res.success, res.stats.status_message()
    assert seen and seen[-1].iteration == res.stats.iterations
    pid = worker._proc.pid
    res = worker.solve(load_problem("case_stand", model=g1))
    assert res.success and worker._proc.pid == pid   # the same worker, its caches kept


def test_a_deadline_kills_the_worker_and_the_next_solve_gets_a_new_one(worker, g1):
    restarts = worker.restarts
    t0 = time.monotonic()
    with pytest.raises(SolveAborted) as err:
        worker.solve(load_problem("case_one_step", model=g1), deadline=0.5)
    assert err.value.code == TIMEOUT and "within 0.5 s" in err.value.message
    assert time.monotonic() - t0 < 10.0
    assert worker.restarts == restarts + 1
    assert worker.solve(load_problem("case_stand", model=g1)).success


def test_cancel_stops_the_solve(worker, g1):
    cancel = threading.Event()
    with pytest.raises(SolveAborted) as err:
        worker.solve(load_problem("case_one_step", model=g1), progress=lambda p: cancel.set(), cancel=cancel)
    assert err.value.code == CANCELLED
