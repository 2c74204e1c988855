"""tools/bench_exec.py executes a plan from prompts (tools/bench_plan.py) with its own contact
schedule, rebuilt from its task file, not the fixture's."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest

_TOOLS = Path(__file__).resolve().parents[2] / "tools"
sys.path.insert(0, str(_TOOLS))   # bench_exec imports bench_plan as its script would
_spec = importlib.util.spec_from_file_location("bench_exec_prompts_under_test", _TOOLS / "bench_exec.py")
bench_exec = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench_exec)


def test_the_task_of_a_saved_result_comes_from_its_summary(tmp_path):
    rows = [{"case": "s1_basket_prompts_box_mass2.5_box_yaw0", "variant": "AllKeyframe",
             "overrides": {"box_mass": 2.5}, "task": "s1_basket"},
            {"case": "s1_basket_mass2.5_yaw0", "variant": "all", "overrides": {}}]
    (tmp_path / "summary.json").write_text(json.dumps({"rows": rows}))
    assert bench_exec.saved_task(tmp_path / "s1_basket_prompts_box_mass2.5_box_yaw0_AllKeyframe.npz") == "s1_basket"
    assert bench_exec.saved_task(tmp_path / "s1_basket_mass2.5_yaw0_all.npz") == ""   # a fixture's
    assert bench_exec.saved_task(tmp_path / "elsewhere" / "x_all.npz") == ""
    # saved before bench_plan recorded its task: the name gives it, if such a task file exists
    assert bench_exec.saved_task(tmp_path / "elsewhere" / "s2_trolley_prompts_box_mass5_AllKeyframe.npz") == "s2_trolley"
    assert bench_exec.saved_task(tmp_path / "elsewhere" / "nosuchtask_prompts_box_mass5_AllKeyframe.npz") == ""


def test_a_plan_from_prompts_gets_its_own_schedule_and_a_wrong_horizon_is_refused():
    from lomanip_to import fixtures

    overrides = {"box_mass": 2.5, "box_yaw": 0.0}
    fixture = fixtures.load_problem("s1_basket", overrides)
    with pytest.raises(ValueError, match="planned with other code or inputs"):
        bench_exec.prompts_problem("s1_basket", overrides, fixture.duration)
    # the horizon bench_plan gives S1 from its prompts (docs/planner_s1.md; session 53: 22.2 s,
    # session 55: 23.52 s with the grab's overhead reach)
    horizon = 23.51941974249487
    prob = bench_exec.prompts_problem("s1_basket", overrides, horizon)
    assert prob.duration == pytest.approx(horizon) and len(prob.phases) != len(fixture.phases)
