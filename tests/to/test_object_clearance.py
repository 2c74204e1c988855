"""A carried object keeps out of the other objects: the clearance rows and the check."""
from types import SimpleNamespace

import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.checks import carried_object_depths
from lomanip_to.discretize import CARRIED_POINT_RADIUS, ProblemData, carried_points
from lomanip_to.fixtures import load_problem


def test_carried_points_touch_the_box_faces_from_inside():
    prob = load_problem("case_lift_box")
    box = prob.object("box")
    pts = carried_points(box)
    half = box.primitives[0].half_extents()
    assert pts.shape == (18, 4)
    assert np.allclose(pts[:, 3], CARRIED_POINT_RADIUS)
    loc = np.abs(pts[:, :3] - np.asarray(box.primitives[0].position, float))
    assert np.all(loc <= half - CARRIED_POINT_RADIUS + 1e-12)
    # every sphere reaches the bottom or the top face exactly
    assert np.allclose(loc[:, 2] + pts[:, 3], half[2])


def test_carried_points_stay_inside_a_thin_primitive():
    # the S1 basket's floor is 1 cm thick: its spheres must not reach below it (they held the
    # basket 5 mm off its shelf at the lift, session 55)
    from lomanip_to.problem import Primitive, SceneObject

    plate = Primitive("box", (0.3, 0.4, 0.01), (0.0, 0.0, -0.09))
    basket = SceneObject("basket", "basket", True, (0.0, 0.0, 0.0), mass=0.5, primitives=[plate])
    pts = carried_points(basket)
    assert np.allclose(pts[:, 3], 0.005)
    z = pts[:, 2]
    assert np.all(z - pts[:, 3] >= -0.095 - 1e-12) and np.all(z + pts[:, 3] <= -0.085 + 1e-12)
    assert np.isclose((z - pts[:, 3]).min(), -0.095)


def test_the_lifted_box_gets_rows_against_the_table_only_while_carried(g1):
    data = ProblemData(load_problem("case_lift_box", model=g1), g1)
    assert data.structure.env_pairs == len(data.env_pairs) > 0
    assert {(oid, po) for oid, _, (po, _) in data.env_pairs} == {("box", "table")}
    win, _ = solver.get_window(g1, data.structure)
    _, _, lbg, ubg, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options, data)[0])
    rows = win.G["e0 carried object collision"]
    for k in range(data.grid.K):
        free = data.obj_mode(k, "box") == "free"
        assert lbg[rows, k][0] == (0.0 if free else -np.inf)
        assert ubg[rows, k][0] == np.inf
    assert any(data.obj_mode(k, "box") == "free" for k in range(data.grid.K))


def test_segments_share_the_whole_problems_clearance_pairs(g1):
    prob = load_problem("s2_trolley", model=g1)
    data = ProblemData(prob, g1)
    t0, t1 = solver.segments(prob)[1]
    poses = {o.id: np.concatenate([np.asarray(o.position, float), o.rpy()]) for o in prob.objects}
    sp = solver.segment_problem(prob, t0, t1, data.x_init, poses)
    sd = ProblemData(sp, g1, moving=data.moving, pairs=data.pairs, stand=data.x_init, env_pairs=data.env_pairs)
    assert sd.structure == data.structure
    # S2's box is carried from the table to the trolley: it has rows against both
    assert {po for _, _, (po, _) in data.env_pairs} == {"table", "trolley"}


def _res_with_box_at(data, z: float):
    poses = np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (data.grid.K, 1))
    box = data.prob.object("box")
    poses[:] = [box.position[0], box.position[1], z, 0.0, 0.0, 0.0]
    return SimpleNamespace(object_pose_knots={"box": poses})


def test_the_check_measures_a_carried_box_sunk_into_the_table(g1):
    data = ProblemData(load_problem("case_lift_box", model=g1), g1)
    box, table = data.prob.object("box"), data.prob.object("table")
    k = next(k for k in range(data.grid.K) if data.obj_mode(k, "box") == "free")
    rest = table.position[2] + table.top_z() - box.bottom_z()
    assert carried_object_depths(data, _res_with_box_at(data, rest + 0.01), k) == []
    assert max(carried_object_depths(data, _res_with_box_at(data, rest - 0.04), k)) == pytest.approx(0.04, abs=1e-6)
    # a box resting on its support is the support rows' business, not a penetration
    k_rest = next(k for k in range(data.grid.K) if data.obj_mode(k, "box") != "free")
    assert carried_object_depths(data, _res_with_box_at(data, rest - 0.04), k_rest) == []
