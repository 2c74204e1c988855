"""What a subtask segment hands the next one: object poses without the solver's drift."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import ObjectMotion


def _segment(g1, prob, t0, t1):
    poses = {o.id: np.concatenate([np.asarray(o.position, float), o.rpy()]) for o in prob.objects}
    sp = solver.segment_problem(prob, t0, t1, prob.initial_configuration, poses)
    whole = ProblemData(prob, g1)
    return ProblemData(sp, g1, moving=whole.moving, pairs=whole.pairs, stand=whole.x_init, env_pairs=whole.env_pairs), poses


def _drifted_end(win, sd, oid, drift):
    Wm = np.zeros((win.W.n, sd.grid.K + 1))
    j = sd.midx[oid]
    Wm[win.W[f"o{j}_pose"], :] = np.asarray(sd.obj_nom[oid]).T[:, :1] + drift[:, None]
    return Wm


def test_an_unmoved_object_keeps_its_pose_exactly(g1):
    prob = load_problem("s1_basket", model=g1)
    sd, poses = _segment(g1, prob, 0.0, 3.0)   # walk to the box: the box never moves
    assert all(sd.obj_mode(k, "box") == "fixed" for k in range(sd.grid.K))
    win, _ = solver.get_window(g1, sd.structure)
    drift = np.array([-3.8e-4, 0, 2.8e-4, 0, -9e-5, 0])   # S1's subtask 0 left the box like this
    out = solver._poses_at_end(win, sd, _drifted_end(win, sd, "box", drift), poses)
    np.testing.assert_array_equal(out["box"], poses["box"])


def test_an_object_resting_on_a_support_is_put_back_on_it(g1):
    prob = load_problem("s1_basket", model=g1)
    for ph in prob.phases:   # as the planner writes S1: the box left on the floor after the place
        if 11.2 <= ph.start < 12.6:
            ph.objects["box"] = ObjectMotion(mode="supported", support="floor")
    sd, poses = _segment(g1, prob, 3.0, 11.6)
    k = sd.grid.K - 1
    assert sd.obj_mode(k, "box") == "supported"
    win, _ = solver.get_window(g1, sd.structure)
    Wm = np.zeros((win.W.n, sd.grid.K + 1))
    j = sd.midx["box"]
    end = np.array([1.41, 0.98, 0.15 + 3e-4, 2e-4, -1e-4, 0.03])
    Wm[win.W[f"o{j}_pose"], k] = end
    out = solver._poses_at_end(win, sd, Wm, poses)
    box = prob.object("box")
    np.testing.assert_allclose(out["box"][[0, 1, 5]], end[[0, 1, 5]])   # where the solve put it
    assert abs(out["box"][2] - (0.0 - box.bottom_z())) < 1e-12           # on the floor
    np.testing.assert_array_equal(out["box"][3:5], [0.0, 0.0])           # flat


def test_a_failed_segments_result_is_put_on_the_plans_clock():
    """``on_plan_clock``: the result of a segment whose problem starts at 0 moves to where the
    segment starts, knots, violation and penetration times and the checks' places alike (a failed
    S2 carry said "at t=0.00 s" for a violation at 3.0 s)."""
    from types import SimpleNamespace

    from lomanip_to.result import SolverStats, Violation

    stats = SolverStats(max_constraint_violation=Violation(4.8e-2, 0.0, "CoM consistency"),
                        max_contact_violation=Violation(2e-2, 1.5, "right foot no slip"), max_penetration_time=6.2)
    stats.checks = {"foot_slip": {"value": 0.02, "where": "right_foot t=1.50", "ok": False},
                    "penetration": {"value": 0.05, "where": "t=6.20", "between_knots_where": "t=5.90", "ok": False},
                    "placement_goals": {"value": 0.3, "where": "", "ok": False}}
    res = SimpleNamespace(t_knots=np.array([0.0, 0.2, 0.4]), stats=stats)
    solver.on_plan_clock(res, 3.0)
    np.testing.assert_allclose(res.t_knots, [3.0, 3.2, 3.4])
    assert stats.max_constraint_violation == Violation(4.8e-2, 3.0, "CoM consistency")
    assert stats.max_contact_violation.time == 4.5 and stats.max_penetration_time == pytest.approx(9.2)
    assert stats.checks["foot_slip"]["where"] == "right_foot t=4.50"
    assert stats.checks["penetration"]["where"] == "t=9.20"
    assert stats.checks["penetration"]["between_knots_where"] == "t=8.90"
    assert stats.checks["placement_goals"]["where"] == ""
    assert "at t=3.00 s, CoM consistency" in stats.status_message()
    assert "penetration 0.0 mm at t=9.20 s" in stats.status_message()
