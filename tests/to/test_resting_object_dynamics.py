"""Options.resting_object_dynamics: a resting object the hands touch is held by its support's
friction, not by an immovable support."""

from dataclasses import replace

import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import HANDS


def _touched_resting_knots(sd, oid):
    return [k for k in range(sd.grid.K) if sd.obj_mode(k, oid) == "fixed"
            and any((c := sd.contact(k, h)) is not None and c.object_id == oid for h in HANDS)]


def test_only_touched_resting_knots_get_the_support_and_only_with_the_option(g1):
    prob = load_problem("case_lift_box", model=g1)
    off = ProblemData(prob, g1)
    on = ProblemData(replace(prob, options=prob.options.replaced(resting_object_dynamics=True)), g1)
    touched = _touched_resting_knots(on, "box")
    assert touched  # case_lift_box's hands take the box before it leaves the table
    assert not any(off.resting_under_hands(k, "box") for k in range(off.grid.K))
    assert all(on.resting_under_hands(k, "box") for k in touched)
    untouched_fixed = [k for k in range(on.grid.K) if on.obj_mode(k, "box") == "fixed" and k not in touched]
    assert untouched_fixed and not any(on.resting_under_hands(k, "box") for k in untouched_fixed)


def test_hands_on_a_resting_box_push_it_no_harder_than_its_support_holds(g1):
    """With the option the hands' net horizontal force on the box resting on the table stays within
    the support's friction (0.5 of its normal force: the TO's four corner pyramids of 0.5/sqrt 2),
    the normal force being the box's weight plus the hands' push down; the plan still lifts it."""
    prob = load_problem("case_lift_box", model=g1)
    prob = replace(prob, options=prob.options.replaced(resting_object_dynamics=True))
    res = solver.solve(prob, model=g1)
    assert res.stats.converged and res.stats.success
    mass = prob.object("box").mass
    sd = ProblemData(prob, g1)
    checked = 0
    for k in _touched_resting_knots(sd, "box"):
        hands = [h for h in HANDS if res.contact_objects_knots[h][k] == "box"]
        on_box = -sum(res.forces_knots[h][k] for h in hands)  # Newton's third law
        normal = mass * 9.81 - on_box[2]
        assert normal > 0.0
        assert np.linalg.norm(on_box[:2]) <= 0.5 * normal + 0.5, (k, on_box)
        checked += 1
    assert checked >= 2
    z = res.object_pose_knots["box"][:, 2]
    assert z[-1] - z[0] > 0.05
