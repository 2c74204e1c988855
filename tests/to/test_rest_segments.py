"""Subtasks are also cut at their rest points (Options.rest_segments): where the robot has stood in
double stance for a while and walking starts or the hands' grip changes."""
import numpy as np
import pytest

from lomanip_to import solver
from lomanip_to.discretize import ProblemData
from lomanip_to.fixtures import load_problem
from lomanip_to.model import FEET, rpy_to_rot


@pytest.fixture(scope="module")
def s1(g1):
    return load_problem("s1_basket", model=g1)


def _scene_poses(prob):
    return {o.id: np.concatenate([np.asarray(o.position, float), o.rpy()]) for o in prob.objects}


def _phase_ending(prob, t):
    return next(ph for ph in prob.phases if abs(ph.end - t) < 1e-9)


def _phase_starting(prob, t):
    return next(ph for ph in prob.phases if abs(ph.start - t) < 1e-9)


def test_rest_points_of_s1(s1):
    rest = solver.rest_points(s1)
    # after the lift (walking starts), before the last steps and before the hands take the basket
    # (whose lift makes the piece after it 1.6 s long); not at the release (11.6 s)
    assert rest == pytest.approx([4.4, 14.2, 16.6])
    subtask_ends = [t1 for _, t1 in solver.segments(s1, rest=False)]
    for t in rest:
        before, after = _phase_ending(s1, t), _phase_starting(s1, t)
        assert before.subtask_index == after.subtask_index and t not in subtask_ends
        assert before.phase_type == "stance" and all(f in before.contacts for f in FEET)
        assert before.end - before.start >= solver.REST_MIN_STANCE - 1e-9
        hands = lambda ph: {h: c.object_id for h, c in ph.contacts.items() if h.endswith("hand")}
        assert after.phase_type == "walking" or hands(after) != hands(before)
        assert set(hands(before).items()) <= set(hands(after).items())  # no release
    segs = solver.segments(s1, rest=True)
    assert segs[0][0] == 0.0 and segs[-1][1] == pytest.approx(s1.duration)
    assert all(abs(a[1] - b[0]) < 1e-12 for a, b in zip(segs, segs[1:]))
    assert sorted({t for seg in segs for t in seg}) == pytest.approx(sorted({0.0, *subtask_ends, *rest}))
    assert all(t1 - t0 >= solver.REST_MIN_SEGMENT - 1e-9 for t0, t1 in segs)


def test_option_switches_the_cuts(s1):
    from dataclasses import replace

    on = replace(s1, options=replace(s1.options, rest_segments=True))
    off = replace(s1, options=replace(s1.options, rest_segments=False))
    assert solver.segments(off) == solver.segments(s1, rest=False)
    assert solver.segments(on) == solver.segments(s1, rest=True)
    assert len(solver.segments(on)) == len(solver.segments(off)) + 3


def test_no_cut_in_the_middle_of_a_push(g1):
    s2 = load_problem("s2_trolley", model=g1)
    for t in solver.rest_points(s2):
        ph = _phase_ending(s2, t)
        pushed = {o for o, m in ph.objects.items() if m.mode in ("rolling", "supported")}
        held_on = {c.object_id for h, c in _phase_starting(s2, t).contacts.items() if h.endswith("hand")}
        assert not (pushed & held_on), f"cut at {t} s while pushing {pushed & held_on}"
    # S2's push of the trolley starts with a 0.4 s double stance, then walks: no rest point there
    push_start = min(ph.start for ph in s2.phases if "trolley" in ph.objects)
    assert not [t for t in solver.rest_points(s2) if t > push_start]


def test_grip_kept_across_a_cut_in_a_carry(g1, s1):
    """A segment cut mid-carry starts with the box lifted and turned: the grip (contact point and
    normal in the box's frame) is the one the previous segment held, and the keyframe after the
    segment only anchors the warm start (no keyframe cost inside the segment)."""
    data = ProblemData(s1, g1)
    lift = solver.segment_problem(s1, 3.0, 4.4, data.x_init, _scene_poses(s1))
    assert [kf.subtask_index for kf in lift.keyframes] == [1]
    assert ProblemData(lift, g1, moving=data.moving, pairs=data.pairs, stand=data.x_init, env_pairs=data.env_pairs).kf_knots == {}
    t0, t1 = 4.4, 11.6
    pose = np.array([0.9, 0.3, 0.55, 0.05, -0.04, 0.6])  # lifted, tilted, turned
    grips = {"left_hand": ("box", np.array([0.02, 0.2, 0.06]), np.array([0.0, 1.0, 0.0])),
             "right_hand": ("box", np.array([0.01, -0.2, 0.07]), np.array([0.0, -1.0, 0.0]))}
    seg = solver.segment_problem(s1, t0, t1, data.x_init, {**_scene_poses(s1), "box": pose}, grips)
    c = seg.phases[0].contacts["left_hand"]
    R = rpy_to_rot(pose[3:])
    np.testing.assert_allclose(c.position, pose[:3] + R @ grips["left_hand"][1], atol=1e-12)
    sd = ProblemData(seg, g1, moving=data.moving, pairs=data.pairs, stand=data.x_init, env_pairs=data.env_pairs)
    kf_t = [seg.keyframe_time(kf) for kf in seg.keyframes]
    assert sorted(sd.grid.t[k] for k in sd.kf_knots) == pytest.approx([t for t in kf_t if t <= t1 - t0 + 1e-9])
    win, _ = solver.get_window(g1, sd.structure)
    _, _, _, _, Pm, _ = sd.fill(win, *solver.homotopy_stages(seg.options)[-1])
    for k in (0, sd.grid.K // 2, sd.grid.K - 1):
        for h, (_, loc, n) in grips.items():
            if sd.contact(k, h) is None:
                continue
            np.testing.assert_allclose(Pm[win.P[f"{h}_loc"], k], loc, atol=1e-9)
            np.testing.assert_allclose(Pm[win.P[f"{h}_n"], k], n, atol=1e-9)
    # and the solver hands exactly those parameters on at a segment's last knot
    assert set(solver._grips_at_end(win, sd, Pm)) <= set(grips)


def test_carried_object_keeps_its_place_relative_to_the_base(g1, s1):
    """With no placement goal inside a segment, a carried object's nominal rides with the base
    (it does not stay where the segment started while the base walks away)."""
    from dataclasses import replace

    from lomanip_to.discretize import _relative_to_base

    data = ProblemData(s1, g1)
    pose = np.array([0.9, 0.0, 0.6, 0.0, 0.0, 0.0])
    seg = solver.segment_problem(s1, 4.4, 11.6, data.x_init, {**_scene_poses(s1), "box": pose})
    seg_walk = replace(seg, phases=[ph for ph in seg.phases if ph.end <= 5.4 + 1e-9], placement_goals=[],
                       options=replace(seg.options, stepping_warm_start=False))  # x_guess = the nominal
    sd = ProblemData(seg_walk, g1, moving=data.moving, pairs=data.pairs, stand=data.x_init, env_pairs=data.env_pairs)
    X, traj = sd.x_guess, sd.obj_nom["box"]
    rel0 = _relative_to_base(X[0], traj[0])
    for k in range(1, sd.grid.K):
        np.testing.assert_allclose(_relative_to_base(X[k], traj[k]), rel0, atol=1e-6)
    assert np.linalg.norm(X[-1, :2] - X[0, :2]) > 0.3  # the base walked


def test_a_lift_can_go_with_the_segment_before_it(s1):
    """``Options.lift_with_previous_segment``: S1's carry opens with the lift (3.0-4.4 s, the box
    free from its first knot); with the option that phase ends the first segment instead of
    starting the second, so the second starts holding the lifted box at rest. Other cuts stay."""
    from dataclasses import replace

    from lomanip_to.discretize import _lifts

    off = solver.segments(s1)
    on = solver.segments(replace(s1, options=replace(s1.options, lift_with_previous_segment=True)))
    i = next(i for i, ph in enumerate(s1.phases) if ph.start == pytest.approx(off[1][0]))
    assert _lifts(s1.phases, i)   # the second segment opens with the lift
    assert on[0] == pytest.approx((0.0, s1.phases[i].end)) and on[1][0] == pytest.approx(s1.phases[i].end)
    assert on[1:][-1] == off[-1] and len(on) == len(off)
