"""tools/bench_plan.py --solve solves with the task file's TO options, the variant switching the keyframes."""

import importlib.util
from pathlib import Path

_PATH = Path(__file__).resolve().parents[2] / "tools" / "bench_plan.py"
_spec = importlib.util.spec_from_file_location("bench_plan_under_test", _PATH)
bench_plan = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench_plan)


def test_variants_keep_the_task_options():
    task = bench_plan.load_task("s1_basket")
    all_kf = bench_plan.variant_options(task, "AllKeyframe", None)
    none_kf = bench_plan.variant_options(task, "NoKeyframe", 300)
    for opt in (all_kf, none_kf):  # what the plan service would get from the task file
        assert opt.segment_moving_objects is True
        assert opt.dt_lift == task["options"]["dt_lift"]
        assert opt.weights["w_carry_pose"] == task["options"]["weights"]["w_carry_pose"]
        assert opt.ipopt["perturb_always_cd"] == "yes"
    assert all_kf.max_iterations == task["options"]["max_iterations"]
    assert none_kf.max_iterations == 300
    assert (all_kf.use_keyframe_base_cost, all_kf.use_keyframe_foot_cost, all_kf.use_keyframe_warm_start) == (True,) * 3
    assert (none_kf.use_keyframe_base_cost, none_kf.use_keyframe_foot_cost, none_kf.use_keyframe_warm_start) == (False,) * 3
