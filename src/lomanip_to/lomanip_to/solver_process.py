"""The TO in a worker process with a hard wall-clock deadline.

Why: ``Options.time_limit`` is checked between ipopt iterations, but a single iteration can run for
many minutes inside MUMPS (an LDL^T factorisation with the Hessian regularised by 1e10-1e13;
measured on S1 planned from prompts: one iteration over 10 minutes, see docs/to.md). Nothing in the
solver's own thread can interrupt that. A child process can be killed: :class:`SolverProcess` runs
``solver.solve`` in a persistent worker (its compiled problem caches survive between solves),
relays per-iteration progress, and kills and restarts the worker when the deadline passes or the
caller cancels. The caller gets :class:`SolveAborted` (error code TIMEOUT or CANCELLED) instead of
a hang.
"""
from __future__ import annotations

import multiprocessing as mp
import threading
import time
from typing import Callable

from .problem import TIMEOUT, ProblemError

#: lomanip_msgs/ErrorCode.CANCELLED
CANCELLED = -9
#: lomanip_msgs/ErrorCode.FAILURE
FAILURE = 99999
#: the hard deadline is the solver's own time limit plus this much (s) ...
DEADLINE_GRACE = 60.0
#: ... or plus this fraction of it, whichever is larger: the solver stops itself at its time limit
#: at the end of the iteration it is in; only an iteration that overruns by more is killed
DEADLINE_GRACE_FRACTION = 0.25


class SolveAborted(ProblemError):
    """The worker was stopped before the solve ended: deadline passed (TIMEOUT) or cancelled."""


def hard_deadline(time_limit: float) -> float:
    """Seconds after which a solve with ``Options.time_limit`` = ``time_limit`` is killed."""
    return float(time_limit) + max(DEADLINE_GRACE, DEADLINE_GRACE_FRACTION * float(time_limit))


def _worker(conn, threads: int) -> None:
    """Child: solve each problem received, send progress messages and the result (or the error).

    Ctrl-C / SIGINT to the process group is the parent's to handle: the worker ignores it and ends
    when the parent closes the pipe or kills it (before, each shutdown logged a KeyboardInterrupt
    traceback from the idle worker)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from . import solver

    while True:
        try:
            msg = conn.recv()
        except EOFError:
            return
        if msg is None:
            return
        problem = msg
        try:
            res = solver.solve(problem, threads=threads, progress=lambda p: conn.send(("progress", p)))
            conn.send(("result", res))
        except ProblemError as exc:
            conn.send(("problem_error", (exc.code, exc.message, exc.where)))
        except Exception as exc:  # noqa: BLE001 - reported to the caller, the worker stays up
            conn.send(("error", f"{type(exc).__name__}: {exc}"))


class SolverProcess:
    """A persistent TO worker process; one solve at a time (the caller serialises)."""

    def __init__(self, threads: int = 2, poll_period: float = 0.1) -> None:
        self.threads = int(threads)
        self.poll_period = float(poll_period)
        self._ctx = mp.get_context("spawn")   # the parent may hold threads (rclpy): never fork
        self._proc = None
        self._conn = None
        self.restarts = 0   # workers killed (deadline or cancel) so far

    # ------------------------------------------------------------------------------------------
    def _ensure_worker(self) -> None:
        if self._proc is not None and self._proc.is_alive():
            return
        parent, child = self._ctx.Pipe()
        self._proc = self._ctx.Process(target=_worker, args=(child, self.threads), daemon=True,
                                       name="lomanip_to-solver")
        self._proc.start()
        child.close()
        self._conn = parent

    def _kill(self) -> None:
        if self._proc is not None:
            self._proc.kill()
            self._proc.join(timeout=10.0)
        if self._conn is not None:
            self._conn.close()
        self._proc = self._conn = None
        self.restarts += 1

    def close(self) -> None:
        """Stop the worker (a solve in progress is abandoned)."""
        if self._proc is None:
            return
        try:
            self._conn.send(None)
            self._proc.join(timeout=5.0)
        except (OSError, BrokenPipeError):
            pass
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(timeout=5.0)
        self._conn.close()
        self._proc = self._conn = None

    # ------------------------------------------------------------------------------------------
    def solve(self, problem, progress: Callable | None = None, deadline: float | None = None,
              cancel: threading.Event | None = None):
        """``solver.solve(problem)`` in the worker; its TOResult, or :class:`SolveAborted`.

        ``deadline`` (s from now) defaults to :func:`hard_deadline` of the problem's time limit.
        ``ProblemError`` raised in the worker is raised here with its code.
        """
        deadline = hard_deadline(problem.options.time_limit) if deadline is None else float(deadline)
        self._ensure_worker()
        t0 = time.monotonic()
        try:
            self._conn.send(problem)
        except (OSError, BrokenPipeError):   # a worker that died between solves: start a fresh one
            self._kill()
            self._ensure_worker()
            self._conn.send(problem)
        while True:
            if cancel is not None and cancel.is_set():
                self._kill()
                raise SolveAborted(CANCELLED, "optimisation cancelled; solver process stopped")
            elapsed = time.monotonic() - t0
            if elapsed > deadline:
                self._kill()
                raise SolveAborted(TIMEOUT, f"no answer from the solver within {deadline:.3g} s (an ipopt "
                                            f"iteration overran the {problem.options.time_limit:.0f} s time "
                                            f"limit); solver process stopped")
            try:
                ready = self._conn.poll(min(self.poll_period, max(0.0, deadline - elapsed)))
                if not ready:
                    if not self._proc.is_alive():
                        code = self._proc.exitcode
                        self._kill()
                        raise ProblemError(FAILURE, f"the solver process died (exit code {code})")
                    continue
                kind, payload = self._conn.recv()
            except (EOFError, OSError):
                code = self._proc.exitcode if self._proc is not None else None
                self._kill()
                raise ProblemError(FAILURE, f"the solver process died (exit code {code})") from None
            if kind == "progress":
                if progress is not None:
                    progress(payload)
            elif kind == "result":
                return payload
            elif kind == "problem_error":
                raise ProblemError(*payload)
            else:
                raise RuntimeError(f"solver process: {payload}")
