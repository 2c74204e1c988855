"""Task files for `lomanip plan`: the shipped ones load, bad ones say what is wrong."""
from __future__ import annotations

import pytest

from lomanip_launch.task_file import TaskFileError, load_task, task_from_dict


@pytest.mark.parametrize("name", ["s1_basket", "s2_trolley"])
def test_shipped_tasks_load(name):
    task = load_task(name)
    assert task.scenario == name
    assert len(task.prompts) == 3
    assert [g.object_id for g in task.placement_goals] == ["box"]


def test_missing_file_lists_shipped_tasks(tmp_path):
    with pytest.raises(TaskFileError, match="s1_basket, s2_trolley"):
        load_task(str(tmp_path / "nope.yaml"))


@pytest.mark.parametrize("data, match", [
    ({"scenario": "s1_basket", "prompts": []}, "non-empty list"),
    ({"scenario": "s1_basket", "prompts": ["pick up the box", " "]}, "non-empty strings"),
    ({"prompts": ["a"]}, "'scenario'"),
    ({"scenario": "s1_basket", "prompts": ["a"], "placement_goals": [{"object": "box", "position": [1, 2]}]},
     r"\[x, y, z\]"),
    ({"scenario": "s1_basket", "prompts": ["a"], "placement_goals": [{"object": "box", "position": [1, 2, "nan"]}]},
     "finite"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"max_iterations": "many"}}, "must be int"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"warp_speed": True}}, "unknown option"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"inertial_torque_groups": "waist"}}, "must be list"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"inertial_torque_groups": [1]}}, "list of group names"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"solver_options": ["tol"]}}, "must be dict"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"solver_options": {"tol": [1]}}}, "ipopt option names"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"weights": {"w_goal": "big"}}}, "cost weight names to numbers"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"weights": [1.0]}}, "must be dict"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"subtask_options": {"1": {}}}}, "subtask indices"),
    ({"scenario": "s1_basket", "prompts": ["a"], "options": {"subtask_options": {1: True}}}, "subtask indices"),
    ({"scenario": "s1_basket", "prompts": ["a"], "colour": "red"}, "unknown field"),
])
def test_bad_tasks_are_rejected_with_a_reason(data, match):
    with pytest.raises(TaskFileError, match=match):
        task_from_dict(data)


def test_yaml_syntax_error_names_the_file(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("scenario: [s1\n")
    with pytest.raises(TaskFileError, match="broken.yaml"):
        load_task(str(path))


@pytest.mark.parametrize("name", ["s1_basket", "s2_trolley", "push_trolley"])
def test_shipped_tasks_stop_the_to_before_the_planner_gives_up(name):
    """The TO's hard deadline (its time limit + 25 %, at least + 60 s) ends before the planner's
    wait for the TO and the plan client's wait, so a slow solve answers TIMEOUT from the TO node
    rather than leaving it busy."""
    from pathlib import Path

    import yaml
    from lomanip_planner.timeouts import optimisation_timeout, plan_wait
    from lomanip_to.solver_process import hard_deadline

    params = yaml.safe_load((Path(__file__).parents[2] / "ros_ws/config/lomanip.yaml").read_text())
    planner_timeout = params["lomanip_planner"]["ros__parameters"]["optimisation_timeout"]
    options = load_task(name).options
    planner_wait = optimisation_timeout(planner_timeout, options["time_limit"])
    assert hard_deadline(options["time_limit"]) < planner_wait < plan_wait(options, execute=False)


def test_task_options_reach_the_trajectory_options_message():
    """Every option a task file may set is a TrajectoryOptions field of the same type (plan_client copies them)."""
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_launch.task_file import _OPTION_FIELDS

    msg = TrajectoryOptions()
    assert list(msg.inertial_torque_groups) == ["waist"]  # the TO's default (lomanip_to.problem.Options)
    assert msg.single_support_com_lateral == 0.08  # likewise
    for key, kind in _OPTION_FIELDS.items():
        if key in ("solver_options", "weights", "subtask_options"):  # mappings in YAML, arrays in the message
            assert list(getattr(msg, key)) == []
            continue
        assert isinstance(getattr(msg, key), kind), key


def test_every_trajectory_options_field_can_be_set_from_a_task_file():
    """A new TrajectoryOptions field is usable from a task file too (S2's task file once could not
    ask for carry_reach)."""
    from lomanip_msgs.msg import TrajectoryOptions
    from lomanip_launch.task_file import _OPTION_FIELDS

    assert set(TrajectoryOptions.get_fields_and_field_types()) == set(_OPTION_FIELDS)


def test_solver_options_become_solver_option_entries():
    """YAML's yes/no are booleans; ipopt wants the words. Numbers travel as their text."""
    from lomanip_launch.plan_client import goal_from_task

    task = task_from_dict({"scenario": "s1_basket", "prompts": ["a"],
                           "options": {"solver_options": {"perturb_always_cd": True, "tol": 1e-5, "mu_strategy": "monotone"}}})
    entries = {o.name: o.value for o in goal_from_task(task).options.solver_options}
    assert entries == {"perturb_always_cd": "yes", "tol": "1e-05", "mu_strategy": "monotone"}


def test_weights_become_cost_weight_entries():
    from lomanip_launch.plan_client import goal_from_task

    task = task_from_dict({"scenario": "s1_basket", "prompts": ["a"], "options": {"weights": {"w_carry_pose": 500}}})
    assert task.options["weights"] == {"w_carry_pose": 500.0}
    entries = {w.name: w.value for w in goal_from_task(task).options.weights}
    assert entries == {"w_carry_pose": 500.0}


def test_subtask_options_become_subtask_options_entries():
    """Each subtask's options travel as a YAML mapping that reads back to the same values."""
    import yaml

    from lomanip_launch.plan_client import goal_from_task

    over = {2: {"arm_body_self_pairs": True, "weights": {"w_carry_pose": 500.0, "hip_margin": 0.08}}, 1: {"dt_lift": 0.1}}
    task = task_from_dict({"scenario": "s1_basket", "prompts": ["a"], "options": {"subtask_options": over}})
    entries = goal_from_task(task).options.subtask_options
    assert [e.subtask_index for e in entries] == [1, 2]
    assert {e.subtask_index: yaml.safe_load(e.options_yaml) for e in entries} == over


def test_s1_task_asks_for_the_configuration_that_passed_its_checks():
    """docs/to.md, sessions 15-16: perturb_always_cd, the arms' inertial torque rows, the waist yaw range."""
    opts = load_task("s1_basket").options
    assert opts["solver_options"] == {"perturb_always_cd": "yes"}
    assert set(opts["inertial_torque_groups"]) == {"waist", "left_hand", "right_hand"}
    assert opts["waist_yaw_range"] == 0.8
    assert opts["weights"] == {"w_carry_pose": 500.0}  # session 17


@pytest.mark.parametrize("name", ["s1_basket", "s2_trolley", "push_trolley"])
def test_a_run_folder_task_reads_back_as_planned(name, tmp_path):
    """`lomanip plan` writes runs/<run>/task.yaml so a run can be replayed in its own world."""
    from lomanip_launch.plan_cmd import write_task

    task = load_task(name)
    task.scenario_overrides["box_mass"] = 3.0   # as `--set box_mass=3.0` adds it
    write_task(tmp_path / "run" / "task.yaml", task)
    assert load_task(str(tmp_path / "run" / "task.yaml")) == task
