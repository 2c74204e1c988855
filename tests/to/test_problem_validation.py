"""Input validation raises ProblemError with a code BEFORE any solve."""
import copy

import numpy as np
import pytest

from lomanip_to.fixtures import load_problem
from lomanip_to.problem import (INVALID_REQUEST, UNKNOWN_OBJECT, ContactSpec, PlacementGoal,
                                ProblemError, validate_problem)


@pytest.fixture(scope="module")
def lift(g1):
    return load_problem("case_lift_box", model=g1)


def _expect(prob, g1, code, text):
    with pytest.raises(ProblemError) as ei:
        validate_problem(prob, g1)
    assert ei.value.code == code
    assert text in str(ei.value)


def test_valid_fixture_passes(lift, g1):
    validate_problem(lift, g1)


def test_unknown_object_in_keyframe(lift, g1):
    p = copy.deepcopy(lift)
    p.keyframes[0].contacts.append(ContactSpec("left_hand", "ghost", (0, 0, 1)))
    _expect(p, g1, UNKNOWN_OBJECT, "ghost")


def test_unknown_object_in_phase(lift, g1):
    p = copy.deepcopy(lift)
    p.phases[1].contacts["left_hand"] = ContactSpec("left_hand", "nope", (0, 0, 1))
    _expect(p, g1, UNKNOWN_OBJECT, "nope")


def test_overlapping_and_gapped_phases(lift, g1):
    p = copy.deepcopy(lift)
    p.phases[1].start -= 0.1
    _expect(p, g1, INVALID_REQUEST, "overlaps")
    p = copy.deepcopy(lift)
    p.phases[1].start += 0.1
    _expect(p, g1, INVALID_REQUEST, "gap")


def test_nan_in_configuration(lift, g1):
    p = copy.deepcopy(lift)
    j = list(p.keyframes[0].joints)
    j[3] = float("nan")
    p.keyframes[0].joints = tuple(j)
    _expect(p, g1, INVALID_REQUEST, "non-finite")
    p = copy.deepcopy(lift)
    x0 = list(p.initial_configuration)
    x0[0] = float("nan")
    p.initial_configuration = tuple(x0)
    _expect(p, g1, INVALID_REQUEST, "non-finite")


def test_wrong_joint_count(lift, g1):
    p = copy.deepcopy(lift)
    p.keyframes[0].joints = tuple(p.keyframes[0].joints[:28])
    _expect(p, g1, INVALID_REQUEST, "29 joint values")


def test_unreachable_placement(lift, g1):
    p = copy.deepcopy(lift)
    p.placement_goals = [PlacementGoal("box", (5.0, 0.0, 0.8), 0.0)]
    _expect(p, g1, INVALID_REQUEST, "unreachable")
    p.placement_goals = [PlacementGoal("box", (0.3, 0.0, 9.0), 0.0)]
    _expect(p, g1, INVALID_REQUEST, "workspace")


def test_joint_out_of_limits(lift, g1):
    p = copy.deepcopy(lift)
    j = np.array(p.keyframes[0].joints)
    j[g1.joint_names.index("left_knee_joint")] = 3.5
    p.keyframes[0].joints = tuple(j)
    _expect(p, g1, INVALID_REQUEST, "outside limits")


def test_solve_rejects_before_building(lift, g1):
    from lomanip_to import solver

    p = copy.deepcopy(lift)
    p.phases[2].objects = {"ghost": p.phases[2].objects["box"]}
    with pytest.raises(ProblemError) as ei:
        solver.solve(p, g1)
    assert ei.value.code == UNKNOWN_OBJECT


def test_unknown_hessian_option(lift, g1):
    p = copy.deepcopy(lift)
    p.options = p.options.replaced(guide_hessian="gauss-newton")
    _expect(p, g1, INVALID_REQUEST, "options.guide_hessian must be one of exact, cost")


@pytest.mark.parametrize("name, bad", [("interval_momentum_tolerance", -0.1), ("interval_momentum_tolerance", float("nan")),
                                       ("upper_body_acceleration_limit", -1.0),
                                       ("upper_body_acceleration_limit", float("inf")),
                                       ("upper_body_speed_limit", -1.0), ("upper_body_speed_limit", float("nan")),
                                       ("carried_object_clearance", -0.01), ("carried_object_clearance", 0.5),
                                       ("carried_object_clearance", float("nan")), ("dt_lift", -0.1), ("dt_lift", 2.0),
                                       ("dt_reach", -0.1), ("dt_reach", float("nan")),
                                       ("body_object_clearance", -0.01), ("body_object_clearance", 0.5),
                                       ("hand_object_clearance", -0.01), ("hand_object_clearance", float("nan"))])
def test_rows_on_the_motion_between_knots_refuse_bad_values(lift, g1, name, bad):
    p = copy.deepcopy(lift)
    p.options = p.options.replaced(**{name: bad})
    _expect(p, g1, INVALID_REQUEST, f"options.{name} must be")
