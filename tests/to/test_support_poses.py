"""A foot on a moved object stands on the object's solved pose when the stitched segments are checked."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem


def _patch_and_height(data, win, k, foot):
    _, _, _, _, Pm, _ = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    return np.asarray(Pm[win.P[f"{foot}_patch"], k]).ravel(), float(np.asarray(Pm[win.P[f"{foot}_h"], k]).ravel()[0])


def test_foot_patch_follows_the_solved_box_pose(g1):
    data = ProblemData(load_problem("s1_basket", model=g1), g1)
    win, _ = solver.get_window(g1, data.structure)
    on_box = [k for k in range(data.grid.K) if (c := data.contact(k, "left_foot")) is not None and c.object_id == "box"]
    assert on_box, "S1's fixture puts the left foot on the box"
    k = on_box[len(on_box) // 2]
    patch0, h0 = _patch_and_height(data, win, k, "left_foot")
    nominal = data.obj_nom["box"]
    np.testing.assert_allclose(patch0[:2], nominal[on_box[0], :2], atol=1e-9)  # the placement goal

    solved = nominal.copy()
    solved[:, 0] += 0.03   # placed 3 cm further along x and 1 cm lower than the goal
    solved[:, 2] -= 0.01
    data.use_solved_support_poses({"box": solved})
    patch1, h1 = _patch_and_height(data, win, k, "left_foot")
    np.testing.assert_allclose(patch1[:2] - patch0[:2], [0.03, 0.0], atol=1e-9)
    np.testing.assert_allclose(patch1[2:], patch0[2:], atol=1e-9)  # same yaw
    assert abs(h1 - h0 + 0.01) < 1e-9
