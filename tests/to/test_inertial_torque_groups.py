"""Options.inertial_torque_groups: which torque rows carry the inertia of the links beyond the joint."""
import copy

import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_options, load_problem
from lomanip_to.problem import INVALID_REQUEST, TORQUE_GROUPS, ProblemError, validate_problem


def test_groups_are_the_models_torque_row_groups(g1):
    assert set(TORQUE_GROUPS) == set(g1.torque_row_joints)


def test_an_unknown_group_is_refused_before_solving(g1):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(inertial_torque_groups=("waist", "neck"))
    with pytest.raises(ProblemError) as ei:
        validate_problem(prob, g1)
    assert ei.value.code == INVALID_REQUEST and "'neck'" in str(ei.value)


def test_yaml_list_becomes_a_tuple():
    assert load_options({"inertial_torque_groups": []}).inertial_torque_groups == ()
    assert load_options({"inertial_torque_groups": ["waist"]}).inertial_torque_groups == ("waist",)


def test_only_the_named_groups_rows_see_the_motion(g1):
    """On a moving robot the waist rows differ with and without the option; the legs' rows do not."""
    prob = load_problem("case_one_step", model=g1)
    rows = {}
    for groups in (("waist",), ()):
        p = copy.deepcopy(prob)
        p.options = p.options.replaced(inertial_torque_groups=groups)
        data = ProblemData(p, g1)
        assert data.structure.inertial_groups == groups
        win, wd = solver.get_window(g1, data.structure)
        _, _, _, _, Pm, W0 = data.fill(win, 2.0, True, True, True)
        rng = np.random.default_rng(0)
        a, b = W0[:, 3].copy(), W0[:, 3].copy()
        a[win.W["xd"]] = rng.normal(0.0, 0.5, 35)
        b[win.W["xd"]] = rng.normal(0.0, 0.5, 35)
        g = np.asarray(wd.F_gf(a, b, Pm[:, 3])[0]).ravel()
        rows[groups] = g[win.G["joint torques"]]
    # row order: the groups of model.torque_row_joints, each its joints
    sizes = {grp: len(js) for grp, (js, _) in g1.torque_row_joints.items()}
    start, span = 0, {}
    for grp, n in sizes.items():
        span[grp] = slice(start, start + n)
        start += n
    dyn, qs = rows[("waist",)], rows[()]
    assert np.max(np.abs(dyn[span["waist"]] - qs[span["waist"]])) > 1e-3
    for grp in ("left_foot", "right_foot", "left_hand", "right_hand"):
        np.testing.assert_allclose(dyn[span[grp]], qs[span[grp]], atol=1e-12)
