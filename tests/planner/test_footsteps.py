"""Footholds of a walk (lomanip_planner.footsteps): rounds of steps a G1 leg can make."""
import math

import numpy as np
import pytest

from lomanip_planner.footsteps import (FEET, StepLimits, Walk, plan_rounds, round_violation, side_of, step_violation,
                                       uniform_rounds)

LIMITS = StepLimits()


def _walk(start_left, start_right, end_left, end_right) -> Walk:
    start = {"left_foot": np.array(start_left, float), "right_foot": np.array(start_right, float)}
    end = {"left_foot": np.array(end_left, float), "right_foot": np.array(end_right, float)}

    def yaw(feet):
        d = feet["left_foot"] - feet["right_foot"]
        return math.atan2(d[1], d[0]) - math.pi / 2

    route = np.array([0.5 * (start["left_foot"] + start["right_foot"]), 0.5 * (end["left_foot"] + end["right_foot"])])
    return Walk(route, start, end, yaw(start), yaw(end))


def _steps(walk: Walk, rounds):
    """(stance xy, stance yaw, swing from, swing to, swing yaw, side) of every step, in order."""
    out, s0 = [], 0.0
    for s1, lead in rounds:
        other = FEET[1] if lead == FEET[0] else FEET[0]
        out.append((walk.foot(other, s0), walk.heading(s0), walk.foot(lead, s0), walk.foot(lead, s1),
                    walk.heading(s1), side_of(lead), s1))
        if s1 < 1.0:
            out.append((walk.foot(lead, s1), walk.heading(s1), walk.foot(other, s0), walk.foot(other, s1),
                        walk.heading(s1), side_of(other), s1))
        s0 = s1
    return out


def test_feet_paths_start_and_end_exactly_where_asked():
    w = _walk((0.32, 0.11), (0.32, -0.14), (1.03, 1.12), (1.01, 0.88))
    assert np.allclose(w.foot("left_foot", 0.0), (0.32, 0.11))
    assert np.allclose(w.foot("right_foot", 1.0), (1.01, 0.88))


def test_a_straight_walk_keeps_even_rounds():
    w = _walk((0.0, 0.12), (0.0, -0.12), (0.6, 0.12), (0.6, -0.12))
    rounds = plan_rounds(w, "left_foot", LIMITS, 2)
    assert [s for s, _ in rounds] == uniform_rounds(2)
    assert all(lead == "left_foot" for _, lead in rounds)


def test_a_carry_leaving_at_55_degrees_turns_in_small_steps_and_every_step_is_feasible():
    # S1's carry from the pick to the shelf (session 52's uniform rounds: first step 0.45 m aside)
    w = _walk((0.32, 0.11), (0.32, -0.14), (1.03, 1.12), (1.01, 0.88))
    assert w.turning
    even = [(s, "left_foot") for s in uniform_rounds(4)]
    assert round_violation(w, "left_foot", 0.0, 0.25, LIMITS) > 0.1    # what the old rounds did
    rounds = plan_rounds(w, "left_foot", LIMITS, 4)
    assert rounds != even and rounds[-1][0] == 1.0
    s0 = 0.0
    for s1, lead in rounds:
        assert round_violation(w, lead, s0, s1, LIMITS) <= 1e-9
        s0 = s1
    first = _steps(w, rounds)[0]
    assert step_violation(*first[:6], LIMITS) == 0.0


def test_a_quarter_turn_never_puts_one_foot_on_the_other():
    # S2's carry from the table towards the trolley: 0.6 m to the right, turning 94 degrees. With
    # straight-line feet the left foot landed on the right one's foothold
    w = _walk((0.16, 0.04), (0.19, -0.20), (0.26, -0.68), (0.09, -0.69))
    rounds = plan_rounds(w, "left_foot", LIMITS, 3)
    for stance, _, _, to, _, _, _ in _steps(w, rounds):
        assert np.linalg.norm(np.asarray(to) - np.asarray(stance)) > 0.12


@pytest.mark.parametrize("fwd, lat, turn, ok", [(0.3, 0.24, 0.0, True), (0.1, 0.47, 0.0, False),
                                                (0.0, 0.05, 0.0, False), (0.2, 0.24, 1.0, False)])
def test_step_violation_measures_the_leg_s_reach(fwd, lat, turn, ok):
    v = step_violation((0.0, -0.12), 0.0, (0.0, 0.12), (fwd, -0.12 + lat), turn, 1.0, LIMITS)
    assert (v == 0.0) == ok
