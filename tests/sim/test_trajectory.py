"""trajectory: structure, scene and start checks reject bad plans with a code before anything moves."""

import numpy as np
import pytest

from lomanip_sim.robot_model import G1_JOINT_NAMES, G1_STAND_QPOS
from lomanip_sim.trajectory import (INVALID_TRAJECTORY, UNKNOWN_OBJECT, LimbContact, Phase, TrajectoryError,
                                    check_against_scene, check_start, make_trajectory)

N = 5


def _args(n=N):
    t = np.linspace(0.0, 1.0, n)
    q = np.tile(G1_STAND_QPOS[7:], (n, 1))
    base = np.tile(G1_STAND_QPOS[:3], (n, 1))
    quat = np.tile(G1_STAND_QPOS[3:7], (n, 1))
    return t, list(G1_JOINT_NAMES), q, np.zeros_like(q), base, quat


def test_builds_and_interpolates():
    tr = make_trajectory(*_args())
    assert tr.n == N and tr.duration == pytest.approx(1.0)
    assert tr.index_at(-1.0) == (0, 0.0)
    assert tr.index_at(5.0) == (N - 2, 1.0)
    i, s = tr.index_at(0.3)
    assert i == 1 and s == pytest.approx(0.2)
    np.testing.assert_allclose(tr.qpos(0), G1_STAND_QPOS)
    assert tr.qvel(0).shape == (35,)


def test_joint_columns_reordered_by_name():
    t, names, q, qd, base, quat = _args()
    q = q + np.arange(29) * 0.01  # distinct values per joint
    perm = np.random.default_rng(0).permutation(29)
    tr = make_trajectory(t, [names[k] for k in perm], q[:, perm], qd[:, perm], base, quat)
    np.testing.assert_allclose(tr.q, q)


@pytest.mark.parametrize("names, words", [
    ([f"joint_{k}" for k in range(29)], "another robot"),
    (list(G1_JOINT_NAMES[:-1]) + ["left_hip_pitch_joint"], "duplicate"),
])
def test_wrong_joint_names(names, words):
    t, _n, q, qd, base, quat = _args()
    with pytest.raises(TrajectoryError) as e:
        make_trajectory(t, names, q, qd, base, quat)
    assert e.value.code == INVALID_TRAJECTORY and words in e.value.message


def test_other_robot_name():
    with pytest.raises(TrajectoryError, match="robot 'h1'"):
        make_trajectory(*_args(), robot_name="h1")


def test_time_going_backwards():
    t, *rest = _args()
    t[3] = t[1]
    with pytest.raises(TrajectoryError) as e:
        make_trajectory(t, *rest)
    assert e.value.code == INVALID_TRAJECTORY and "does not increase: point 3" in e.value.message


def test_time_grid_must_start_at_zero():
    t, *rest = _args()
    with pytest.raises(TrajectoryError, match="must start at 0"):
        make_trajectory(t + 0.5, *rest)


def test_nan_and_shapes():
    t, names, q, qd, base, quat = _args()
    q[2, 4] = np.nan
    with pytest.raises(TrajectoryError, match="NaN or inf at point 2"):
        make_trajectory(t, names, q, qd, base, quat)
    with pytest.raises(TrajectoryError, match="expected shape"):
        make_trajectory(t, names, q[:3], qd, base, quat)
    with pytest.raises(TrajectoryError, match="at least 2 points"):
        make_trajectory([0.0], names, q[:1], qd[:1], base[:1], quat[:1])


def test_unknown_limb_and_phase_order():
    args = _args()
    c = LimbContact("floor", None, np.array([0.0, 0.0, 1.0]))
    with pytest.raises(TrajectoryError, match="unknown limb 'tail'"):
        make_trajectory(*args, phases=[Phase(0.0, 1.0, {"tail": c})])
    with pytest.raises(TrajectoryError, match="ends .* before it starts"):
        make_trajectory(*args, phases=[Phase(0.5, 0.2, {"left_foot": c})])


def test_scene_check():
    args = _args()
    c = LimbContact("crate", np.zeros(3), np.array([1.0, 0.0, 0.0]))
    tr = make_trajectory(*args, phases=[Phase(0.0, 1.0, {"left_hand": c})])
    check_against_scene(tr, ["crate"])
    with pytest.raises(TrajectoryError) as e:
        check_against_scene(tr, ["box"])
    assert e.value.code == UNKNOWN_OBJECT and "'crate'" in e.value.message


def test_start_check():
    tr = make_trajectory(*_args())
    check_start(tr, G1_STAND_QPOS.copy())
    far = G1_STAND_QPOS.copy()
    far[0] += 0.5
    with pytest.raises(TrajectoryError, match="starts 0.50 m from"):
        check_start(tr, far)
    bent = G1_STAND_QPOS.copy()
    bent[7 + 3] += 1.0
    with pytest.raises(TrajectoryError, match="left_knee_joint"):
        check_start(tr, bent)
    turned = G1_STAND_QPOS.copy()
    turned[3:7] = [np.cos(0.4), 0.0, 0.0, np.sin(0.4)]  # 0.8 rad yaw
    with pytest.raises(TrajectoryError, match="rotated 0.80 rad"):
        check_start(tr, turned)


def test_error_codes_match_messages():
    from lomanip_msgs.msg import ErrorCode

    from lomanip_sim import trajectory as T

    assert (T.INVALID_REQUEST, T.UNKNOWN_OBJECT, T.INVALID_TRAJECTORY, T.EXECUTION_FAILED) == (
        ErrorCode.INVALID_REQUEST, ErrorCode.UNKNOWN_OBJECT, ErrorCode.INVALID_TRAJECTORY, ErrorCode.EXECUTION_FAILED)
