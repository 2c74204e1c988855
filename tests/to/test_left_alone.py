"""An object resting on its support that nothing touches stays at rest (no free floor drive)."""
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import ObjectMotion


def _released_on_the_floor(prob):
    """S1 as the planner writes it: the box set down on the floor (supported, hands on it), then
    left there (supported, no contact) instead of the fixture's 'fixed' after the place."""
    on_floor = ObjectMotion(mode="supported", support="floor")
    for ph in prob.phases:
        if 11.2 <= ph.start < 12.6:
            ph.objects["box"] = on_floor
    return prob


def _velocity_bounds(g1, name, edit=lambda p: p):
    data = ProblemData(edit(load_problem(name, model=g1)), g1)
    win, _ = solver.get_window(g1, data.structure)
    lbw, ubw, _, _, _, _ = data.fill(win, *solver.homotopy_stages(data.prob.options)[-1])
    return data, win, lbw, ubw


def test_a_released_object_on_the_floor_does_not_slide(g1):
    data, win, lbw, ubw = _velocity_bounds(g1, "s1_basket", _released_on_the_floor)
    j = data.midx["box"]
    v = win.W[f"o{j}_vel"]
    N = data.grid.K - 1

    def touched(k):
        return any(c.object_id == "box" for c in data.prob.phases[data.grid.phase[k]].contacts.values())

    supported = [k for k in range(1, N) if data.obj_mode(k, "box") == "supported"
                 and data.obj_mode(k - 1, "box") == "supported"]
    alone = [k for k in supported if not touched(k) and not touched(k - 1)]
    held = [k for k in supported if touched(k) and touched(k - 1)]
    assert alone, "S1 leaves the placed box on the floor"
    for k in alone:
        assert np.all(lbw[v, k] == 0) and np.all(ubw[v, k] == 0), k
    # while the hands are on it, the box on its support may still be moved (set down, slid)
    for k in held:
        assert np.any(ubw[v, k] > 0), k


def test_a_pushed_trolley_may_still_roll(g1):
    data, win, lbw, ubw = _velocity_bounds(g1, "s2_trolley")
    j = data.midx["trolley"]
    v = win.W[f"o{j}_vel"]
    rolling = [k for k in range(1, data.grid.K - 1) if data.obj_mode(k, "trolley") == "rolling"
               and data.obj_mode(k - 1, "trolley") == "rolling"]
    assert rolling and all(np.any(ubw[v, k] > 0) for k in rolling)
