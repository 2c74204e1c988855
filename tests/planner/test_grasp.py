"""Two-handed squeezes made antipodal through the object's CoM (lomanip_planner.grasp)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from lomanip_planner.grasp import HAND_FACE_EDGE_MARGIN, antipodal_squeeze
from lomanip_planner.retargeting import LimbTarget
from lomanip_to.problem import Primitive, SceneObject

YAW = 0.5


def _box(yaw: float = YAW, movable: bool = True, com=(0.02, 0.0, -0.01)) -> SceneObject:
    q = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    return SceneObject("box", "box", movable, (1.0, 0.5, 0.8), q, mass=3.0, com=com,
                       primitives=[Primitive("box", (0.3, 0.4, 0.25))])


def _world(obj: SceneObject, local) -> np.ndarray:
    c, s = math.cos(obj.yaw()), math.sin(obj.yaw())
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(obj.position) + R @ np.asarray(local, float), R


def _squeeze(obj: SceneObject, left_local, right_local) -> list[LimbTarget]:
    pl, R = _world(obj, left_local)
    pr, _ = _world(obj, right_local)
    return [LimbTarget("left_foot", np.zeros(3)),
            LimbTarget("left_hand", pl, R @ [0.0, 1.0, 0.0], obj.id),
            LimbTarget("right_hand", pr, R @ [0.0, -1.0, 0.0], obj.id)]


def _local(obj: SceneObject, target: LimbTarget) -> np.ndarray:
    _, R = _world(obj, np.zeros(3))
    return R.T @ (target.position - np.asarray(obj.position))


def test_hands_move_along_their_faces_to_the_com_line_at_one_height():
    box = _box()
    out = antipodal_squeeze(_squeeze(box, (-0.05, 0.2, 0.03), (0.04, -0.2, 0.05)), {"box": box})
    left, right = _local(box, out[1]), _local(box, out[2])
    np.testing.assert_allclose(left, (0.02, 0.2, 0.04), atol=1e-12)    # CoM's x, its face, mean height
    np.testing.assert_allclose(right, (0.02, -0.2, 0.04), atol=1e-12)
    assert out[0] is not None and np.all(out[0].position == 0.0)       # feet untouched
    np.testing.assert_allclose(out[1].normal, _squeeze(box, (0, 0, 0), (0, 0, 0))[1].normal)


def test_a_grasp_high_on_the_faces_comes_down_to_the_edge_margin():
    box = _box()
    out = antipodal_squeeze(_squeeze(box, (0.0, 0.2, 0.11), (0.0, -0.2, 0.12)), {"box": box})
    assert _local(box, out[1])[2] == pytest.approx(0.125 - HAND_FACE_EDGE_MARGIN)
    assert _local(box, out[2])[2] == pytest.approx(0.125 - HAND_FACE_EDGE_MARGIN)


@pytest.mark.parametrize("case", ["one hand", "fixed object", "rolling", "same side", "two objects"])
def test_anything_but_a_squeeze_of_a_movable_object_is_none(case):
    box = _box(movable=case != "fixed object")
    contacts = _squeeze(box, (-0.05, 0.2, 0.03), (0.04, -0.2, 0.05))
    objects = {"box": box}
    if case == "one hand":
        contacts = contacts[:2]
    if case == "same side":
        contacts[2] = LimbTarget("right_hand", contacts[2].position, contacts[1].normal, "box")
    if case == "two objects":
        objects["crate"] = _box()
        contacts[2] = LimbTarget("right_hand", contacts[2].position, contacts[2].normal, "crate")
    rolling = frozenset({"box"}) if case == "rolling" else frozenset()
    assert antipodal_squeeze(contacts, objects, rolling) is None
