"""tools/bench_push.py --problems: a graph run's own saved plan becomes a case without a re-solve."""

import importlib.util
from pathlib import Path

_PATH = Path(__file__).resolve().parents[2] / "tools" / "bench_push.py"
_spec = importlib.util.spec_from_file_location("bench_push_under_test", _PATH)
bench_push = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench_push)


def _run(tmp_path: Path, with_result: bool) -> Path:
    logs = tmp_path / "runs" / "20261206-041500" / "logs"
    logs.mkdir(parents=True)
    (logs / "to_problem_2.pkl").write_bytes(b"problem")
    if with_result:
        (logs / "to_result_2.npz").write_bytes(b"result")
    return logs / "to_problem_2.pkl"


def test_a_run_s_saved_result_seeds_its_case(tmp_path):
    problem = _run(tmp_path, with_result=True)
    out = tmp_path / "out"
    bench_push.seed_from_run(problem, out)
    case = out / "20261206-041500_2"
    assert bench_push.problem_case_name(problem) == case.name
    assert (case / "plan.npz").read_bytes() == b"result" and (case / "problem.pkl").read_bytes() == b"problem"
    # a case that already has a plan (an earlier --problems re-solve) is left as it is
    (case / "plan.npz").write_bytes(b"re-solved")
    bench_push.seed_from_run(problem, out)
    assert (case / "plan.npz").read_bytes() == b"re-solved"


def test_a_run_without_a_saved_result_seeds_nothing(tmp_path):
    problem = _run(tmp_path, with_result=False)   # a run from before the TO node saved its results
    bench_push.seed_from_run(problem, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_exec_trace_names_a_run_folder_s_missing_result(tmp_path):
    """tools/exec_trace.py runs/<run>: one line naming the missing file, exit 2, nothing simulated."""
    import subprocess
    import sys

    run = tmp_path / "20261206-041500"
    (run / "logs").mkdir(parents=True)
    (run / "task.yaml").write_text("scenario: s2_trolley\nprompts: [push the trolley forward]\n")
    tool = Path(__file__).resolve().parents[2] / "tools" / "exec_trace.py"
    out = subprocess.run([sys.executable, str(tool), str(run)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert "to_result_1.npz" in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_exec_trace_refuses_unknown_joint_names(tmp_path):
    """tools/exec_trace.py --joints: a name that is no G1 joint is one line and exit 2, before loading anything."""
    import subprocess
    import sys

    tool = Path(__file__).resolve().parents[2] / "tools" / "exec_trace.py"
    out = subprocess.run([sys.executable, str(tool), str(tmp_path / "plan.npz"), "--joints", "right_knee_joint,elbow"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert "elbow" in out.stderr and "right_knee_joint" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
