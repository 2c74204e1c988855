"""Options.ipopt (the message's solver_options): ipopt checks names and values before any solve.
Options.weights (the message's weights): known names, finite values >= 0."""
import pytest

from lomanip_to.fixtures import load_problem
from lomanip_to.problem import (INVALID_REQUEST, ProblemError, check_ipopt_options, check_weights, parse_option_value,
                                validate_problem)


def test_text_values_take_ipopts_types():
    assert parse_option_value("5") == 5 and isinstance(parse_option_value("5"), int)
    assert parse_option_value("1e-5") == pytest.approx(1e-5)
    assert parse_option_value("yes") == "yes"


def test_valid_options_pass():
    check_ipopt_options({"perturb_always_cd": "yes", "mu_strategy": "monotone", "tol": 1e-5})
    check_ipopt_options({})


@pytest.mark.parametrize("opts, match", [
    ({"perturb_always_cd": "maybe"}, 'Setting: "maybe" is not a valid setting for Option: perturb_always_cd'),
    ({"warp_speed": 1}, "No such IPOPT option: warp_speed"),
    ({"max_iter": 5}, "max_iter cannot be set here"),
    ({"linear_solver": "ma57"}, "linear_solver cannot be set here"),
])
def test_bad_options_are_refused_with_ipopts_reason(opts, match):
    with pytest.raises(ProblemError, match=match) as ei:
        check_ipopt_options(opts)
    assert ei.value.code == INVALID_REQUEST


def test_validate_problem_refuses_a_bad_option_before_solving(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(ipopt={"perturb_always_cd": "maybe"})
    with pytest.raises(ProblemError, match="perturb_always_cd") as ei:
        validate_problem(prob, g1)
    assert ei.value.code == INVALID_REQUEST


def test_task_files_solver_options_become_options_ipopt():
    from lomanip_to.fixtures import load_options

    opt = load_options({"solver_options": {"perturb_always_cd": True, "tol": 1e-5}},
                       load_options({"ipopt": {"mu_strategy": "monotone"}}))
    assert opt.ipopt == {"mu_strategy": "monotone", "perturb_always_cd": "yes", "tol": 1e-5}


def test_known_weights_pass():
    check_weights({"w_carry_pose": 500.0, "w_goal": 0})
    check_weights({})


@pytest.mark.parametrize("weights, match", [
    ({"w_carry_pos": 500.0}, "unknown weight 'w_carry_pos'"),
    ({"w_carry_pose": -1.0}, "w_carry_pose must be a finite number >= 0"),
    ({"w_goal": float("nan")}, "w_goal must be a finite number >= 0"),
])
def test_bad_weights_are_refused(weights, match):
    with pytest.raises(ProblemError, match=match) as ei:
        check_weights(weights)
    assert ei.value.code == INVALID_REQUEST


def test_validate_problem_refuses_an_unknown_weight_before_solving(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(weights={"w_typo": 1.0})
    with pytest.raises(ProblemError, match="w_typo") as ei:
        validate_problem(prob, g1)
    assert ei.value.code == INVALID_REQUEST
