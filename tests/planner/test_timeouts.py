"""The planner's and the plan client's waits follow the request's own TO time limit."""
import pytest

from lomanip_planner.timeouts import optimisation_timeout, plan_wait
from lomanip_to.solver_process import hard_deadline


def test_a_short_time_limit_keeps_the_configured_timeout():
    assert optimisation_timeout(1800.0, 600.0) == 1800.0


def test_a_long_time_limit_waits_for_the_to_hard_deadline():
    wait = optimisation_timeout(1800.0, 2400.0)
    assert wait > hard_deadline(2400.0) > 2400.0
    assert wait == pytest.approx(hard_deadline(2400.0) + 60.0)


def test_a_missing_time_limit_keeps_the_configured_timeout():
    assert optimisation_timeout(900.0, 0.0) == 900.0


def test_the_client_waits_longer_than_the_planner_and_longer_still_when_executing():
    options = {"time_limit": 2400.0}
    planning = plan_wait(options, execute=False)
    assert planning > optimisation_timeout(0.0, 2400.0)
    assert plan_wait(options, execute=True) > planning
    assert plan_wait({}, execute=False) == 1800.0     # the message default (600 s) keeps the floor
