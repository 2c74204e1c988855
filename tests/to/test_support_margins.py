"""Balance margins the Options can ask of a plan: the CoM over a single stance's sole, and the
centroidal moment pivot near the centre of pressure (Options.single_support_com_margin,
single_support_com_lateral, max_cmp_offset)."""
import casadi as ca
import numpy as np

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import FEET, SOLE_CENTER, SOLE_FORCE_POINTS


def _filled(g1, **options):
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(**options)
    data = ProblemData(prob, g1)
    win, _ = solver.get_window(g1, data.structure)
    return data, win, data.fill(win, 2.0, True, True, True)


def _single_stance_knots(data):
    out = []
    for k in range(data.grid.K):
        stance = [f for f in FEET if data.contact(k, f) is not None]
        if len(stance) == 1:
            out.append((k, stance[0]))
    return out


def test_margins_switch_off(g1):
    data, win, (_, _, lbg, ubg, _, _) = _filled(g1, single_support_com_margin=None, single_support_com_lateral=None,
                                                 double_support_com_margin=None, max_cmp_offset=0.0)
    assert _single_stance_knots(data)
    for name in ("left_foot CoM over the sole", "right_foot CoM over the sole", "angular momentum rate (CMP offset)",
                 "CoM inside the double stance"):
        assert np.all(np.isinf(lbg[win.G[name], :])) and np.all(np.isinf(ubg[win.G[name], :]))


def test_defaults_bound_the_com_and_the_cmp(g1):
    from lomanip_to.problem import Options

    opt = Options()
    assert opt.single_support_com_margin == 0.0 and opt.single_support_com_lateral == 0.08
    assert opt.double_support_com_margin == 0.02 and opt.max_cmp_offset == 0.005


def test_single_stance_bounds_the_com_along_and_across_the_stance_sole(g1):
    data, win, (_, _, lbg, ubg, _, _) = _filled(g1, single_support_com_margin=0.01, single_support_com_lateral=0.08,
                                                 max_cmp_offset=0.03)
    along = SOLE_FORCE_POINTS[:, 0] - SOLE_CENTER[0]
    single = _single_stance_knots(data)
    assert single
    for k, foot in single:
        row = win.G[f"{foot} CoM over the sole"]
        np.testing.assert_allclose(lbg[row, k], [along.min() - 0.01, -0.08])
        np.testing.assert_allclose(ubg[row, k], [along.max() + 0.01, 0.08])
        other = [f for f in FEET if f != foot][0]
        assert np.all(np.isinf(ubg[win.G[f"{other} CoM over the sole"], k]))
    double = [k for k in range(data.grid.K) if all(data.contact(k, f) is not None for f in FEET)]
    assert double
    for k in double:  # the support polygon of a double stance is not one sole: no bound
        assert np.all(np.isinf(ubg[win.G["left_foot CoM over the sole"], k]))
    cmp_row = win.G["angular momentum rate (CMP offset)"]
    np.testing.assert_allclose(ubg[cmp_row, :-1], 0.03)
    assert np.all(np.isinf(ubg[cmp_row, -1]))  # the last knot's window ends the horizon


def test_rows_measure_the_com_in_the_sole_frame_and_the_moment_about_the_com(g1):
    data, win, (_, _, _, _, Pm, W0) = _filled(g1, single_support_com_margin=0.0)
    g = ca.Function("g", [win.a, win.b, win.p], [win.g])
    k, foot = _single_stance_knots(data)[0]
    a = W0[:, k].copy()
    x = a[win.W["x"]]
    num = g1.numeric(x)
    a[win.W["com"]] = np.asarray(num["com"], float).ravel()
    # one known force on the left sole's corners: 1 m g straight up at each corner's force point
    u = np.zeros((3, 4))
    u[2, :] = 0.25
    a[win.W["u_left_foot"]] = u.ravel(order="F")
    for f in ("u_right_foot", "u_left_hand", "u_right_hand", "tau_left_hand", "tau_right_hand"):
        a[win.W[f]] = 0.0
    val = np.array(g(a, W0[:, k + 1], Pm[:, k])).ravel()
    p, R = num["limbs"][foot]
    d = np.asarray(num["com"], float).ravel()[:2] - np.asarray(p, float).ravel()[:2]
    R = np.asarray(R, float)
    np.testing.assert_allclose(val[win.G[f"{foot} CoM over the sole"]], [R[0:2, 0] @ d, R[0:2, 1] @ d], atol=1e-9)
    tree = num["tree"]
    jid = g1.limb_joint["left_foot"]
    pts = [np.asarray(tree["p"][jid], float).ravel() + np.asarray(tree["R"][jid], float) @ SOLE_FORCE_POINTS[i]
           for i in range(4)]
    com = np.asarray(num["com"], float).ravel()
    torque = sum(np.cross(pt - com, u[:, i]) for i, pt in enumerate(pts))
    np.testing.assert_allclose(val[win.G["angular momentum rate (CMP offset)"]], torque[:2], atol=1e-9)


def test_one_step_keeps_its_com_over_the_stance_sole(g1):
    """A solve with the margins. Without them this step's plan has its CoM up to 6.2 cm across the
    stance sole and a CMP 4.1 cm from the centre of pressure; with them every single-stance knot
    stays within 5 cm across and the sole's force points along, and the CMP within 3 cm."""
    prob = load_problem("case_one_step", model=g1)
    prob.options = prob.options.replaced(single_support_com_margin=0.0, single_support_com_lateral=0.05,
                                         max_cmp_offset=0.03)
    res = solver.solve(prob, g1)
    assert res.stats.converged, res.stats.status_message()
    along = SOLE_FORCE_POINTS[:, 0] - SOLE_CENTER[0]
    checked = 0
    for k, t in enumerate(res.t_knots):
        stance = [f for f in FEET if res.contact_objects_knots[f][k]]
        if len(stance) != 1:
            continue
        p, R = g1.numeric(res.x_knots[k])["limbs"][stance[0]]
        d = res.com_knots[k, :2] - np.asarray(p, float).ravel()[:2]
        R = np.asarray(R, float)
        a, c = R[0:2, 0] @ d, R[0:2, 1] @ d
        assert along.min() - 1e-3 <= a <= along.max() + 1e-3, (t, a)
        assert abs(c) <= 0.05 + 1e-3, (t, c)
        checked += 1
    assert checked >= 3
    mg = g1.mass * 9.81
    rate = np.diff(res.h_knots[:, 3:5], axis=0) / np.diff(res.t_knots)[:, None] / mg
    assert np.abs(rate).max() <= 0.03 + 1e-3


def test_double_stance_row_spans_both_soles(g1):
    """The double stance's support: along the heading from the rear sole's to the front sole's
    force points, across between the outer ones, the margin inside."""
    data, win, (_, _, lbg, ubg, Pm, W0) = _filled(g1, double_support_com_margin=0.02)
    row = win.G["CoM inside the double stance"]
    double = [k for k in range(data.grid.K) if all(data.contact(k, f) is not None for f in FEET)]
    along = SOLE_FORCE_POINTS[:, 0] - SOLE_CENTER[0]
    for k in double:
        np.testing.assert_allclose(ubg[row, k][[1, 3]], [along.max() - 0.02, SOLE_FORCE_POINTS[:, 1].max()
                                                          - SOLE_CENTER[1] - 0.02])
    for k, _ in _single_stance_knots(data):
        assert np.all(np.isinf(ubg[row, k]))
    g = ca.Function("g", [win.a, win.b, win.p], [win.g])
    k = double[0]
    a = W0[:, k].copy()
    num = g1.numeric(a[win.W["x"]])
    sole_l = np.asarray(num["limbs"]["left_foot"][0], float).ravel()[:2]
    sole_r = np.asarray(num["limbs"]["right_foot"][0], float).ravel()[:2]
    yaw = a[win.W["x"]][5]
    head, lat = np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])
    mid = 0.5 * (sole_l + sole_r)
    for shift, inside in ((0.0, True), (-(abs((sole_l - sole_r) @ head) / 2 + along.max()), False)):
        com = mid + shift * head
        a[win.W["com"].start:win.W["com"].start + 2] = com
        val = np.array(g(a, W0[:, k + 1], Pm[:, k])).ravel()[row]
        ok = np.all(val >= lbg[row, k] - 1e-6) and np.all(val <= ubg[row, k] + 1e-6)
        assert ok == inside, (shift, val)


def test_knees_stay_bent_after_the_first_phase(g1):
    data, win, (lbw, _, _, _, _, _) = _filled(g1, min_knee_bend=0.3)
    knees = [6 + g1.joint_names.index(f"{s}_knee_joint") for s in ("left", "right")]
    x = win.W["x"]
    first_end = data.prob.phases[0].end
    for k, t in enumerate(data.grid.t[:data.grid.K]):
        lo = lbw[x, k][knees]
        if k == 0 or t < first_end - 1e-9:
            assert np.all(lo < 0.3), (k, lo)  # the measured start stands on straight knees
        else:
            np.testing.assert_allclose(lo, 0.3)


def test_double_stance_row_counts_the_carried_box_when_asked(g1):
    """Options.load_in_double_support_margin: where the hands carry the box (free, held), the
    double stance's CoM is the robot's and the box's together; elsewhere, and with the option off
    (the default), the robot's alone."""
    from lomanip_to.model import HANDS

    def filled(on):
        prob = load_problem("case_lift_box", model=g1)
        prob.options = prob.options.replaced(load_in_double_support_margin=on)
        data = ProblemData(prob, g1)
        win, _ = solver.get_window(g1, data.structure)
        return data, win, data.fill(win, 2.0, True, True, True)

    off_data, off_win, (*_, Pm_off, W0) = filled(False)
    data, win, (*_, Pm, _) = filled(True)
    assert not off_data.structure.load_in_support and data.structure.load_in_support
    row = win.G["CoM inside the double stance"]
    g_on = ca.Function("g", [win.a, win.b, win.p], [win.g])
    g_off = ca.Function("g", [off_win.a, off_win.b, off_win.p], [off_win.g])
    j = data.midx["box"]
    box_mass = load_problem("case_lift_box", model=g1).object("box").mass
    carried = 0
    for k in range(data.grid.K - 1):
        if not all(data.contact(k, f) is not None for f in FEET):
            continue
        held = data.obj_mode(k, "box") == "free" and any(
            (c := data.contact(k, h)) is not None and c.object_id == "box" for h in HANDS)
        assert Pm[win.P[f"o{j}_held"], k] == float(held)
        on = np.array(g_on(W0[:, k], W0[:, k + 1], Pm[:, k])).ravel()[row]
        off = np.array(g_off(W0[:, k], W0[:, k + 1], Pm_off[:, k])).ravel()[off_win.G["CoM inside the double stance"]]
        if not held:
            np.testing.assert_allclose(on, off, atol=1e-12)
            continue
        carried += 1
        com = W0[win.W["com"], k]
        box = W0[win.W[f"o{j}_pose"], k][:3]
        both = (g1.mass * com + box_mass * box) / (g1.mass + box_mass)
        yaw = W0[win.W["x"], k][5]
        head = np.array([np.cos(yaw), np.sin(yaw)])
        np.testing.assert_allclose(on[0] - off[0], head @ (both - com)[:2], atol=1e-9)
    assert carried >= 2
