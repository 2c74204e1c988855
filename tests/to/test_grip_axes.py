"""lomanip_to.transcription.grip_axes: which rotations a hand's grip holds on a surface."""
import numpy as np
import pytest

from lomanip_to.transcription import grip_axes


@pytest.mark.parametrize("n", [(0, 1, 0), (0, -1, 0), (1, 0, 0), (0, 0, 1), (0.05, 0.998, 0.0)])
def test_a_flat_face_holds_every_rotation(n):
    assert np.allclose(grip_axes(n), np.eye(3))


def test_a_bar_lets_the_hand_roll_about_it():
    # the trolley's handle: a bar along the object's y axis, the hand on its back-upper side
    P = grip_axes((-0.8, 0.0, 0.6))
    assert np.allclose(P @ [0, 1, 0], 0.0)  # rolling about the bar is free
    assert np.allclose(P @ [1, 0, 0], [1, 0, 0]) and np.allclose(P @ [0, 0, 1], [0, 0, 1])


def test_a_normal_oblique_to_every_axis_holds_every_rotation():
    assert np.allclose(grip_axes((0.5, 0.5, 0.707)), np.eye(3))
