"""TOResult.save / TOResult.load round trip (the execution benchmark reads the saved files)."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.fixtures import load_problem
from lomanip_to.result import TOResult


def test_save_load_round_trip(g1, tmp_path):
    res = solver.solve(load_problem("case_stand", model=g1), g1)
    path = tmp_path / "stand.npz"
    res.save(path)
    back = TOResult.load(path)
    assert back.joint_names == res.joint_names and back.limbs == res.limbs
    assert back.object_ids == res.object_ids
    assert back.contact_objects_knots == res.contact_objects_knots
    for name in ("t_knots", "x_knots", "xd_knots", "com_knots", "h_knots", "penetration_knots",
                 "t", "joint_positions", "base_quat_xyzw", "com"):
        assert np.array_equal(getattr(back, name), getattr(res, name)), name
    for limb in res.limbs:
        assert np.array_equal(back.forces_knots[limb], res.forces_knots[limb])
        assert np.array_equal(back.forces[limb], res.forces[limb])
    assert back.stats.converged == res.stats.converged and back.success == res.success
    assert back.stats.iterations == res.stats.iterations
    assert back.stats.max_dynamics_violation.constraint == res.stats.max_dynamics_violation.constraint
    assert back.stats.checks.keys() == res.stats.checks.keys()


def test_load_rejects_other_files(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, meta=np.array('{"format": "something else"}'))
    with pytest.raises(ValueError, match="not a saved TOResult"):
        TOResult.load(path)
