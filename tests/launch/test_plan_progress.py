"""The plan client's progress: a bar on a terminal, log lines elsewhere (files, CI logs)."""
import io
import sys

from lomanip_launch.plan_client import _Progress
from lomanip_msgs.action import Plan


def _feedback(stage: str, iteration: int = 0, progress: float = 0.5) -> Plan.Feedback:
    fb = Plan.Feedback()
    fb.stage, fb.subtask_index, fb.subtask_count = stage, 0, 1
    fb.iteration, fb.progress, fb.message = iteration, progress, f"{stage} message"
    return fb


def test_no_bar_when_stderr_is_not_a_terminal(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    p = _Progress(True)
    assert p.bar is None
    for it in range(1, 31):
        p.update(_feedback("optimisation", it))
    p.close()
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("[lomanip] optimisation")]
    assert len(lines) == 4  # iterations 1-9, 10-19, 20-29, 30: one line per 10, not one per iteration
    assert sys.stderr.getvalue() == ""


def test_bar_on_a_terminal(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(sys, "stderr", Tty())
    p = _Progress(True)
    assert p.bar is not None
    p.update(_feedback("optimisation", 7))
    p.close()
    assert "optimisation 1/1 it 7" in sys.stderr.getvalue()
