"""Symmetric readings of a demonstration: which side of a box the robot works from."""
from __future__ import annotations

import math

import numpy as np

from lomanip_planner.retargeting import LimbTarget
from lomanip_planner.symmetry import best_grasp_match, rotate_about, stance_cost, yaw_symmetries
from lomanip_to.problem import Primitive, SceneObject
from lomanip_to.route import footprint_of


def _box(size, com=(0.0, 0.0, 0.0)):
    return SceneObject("box", "box", True, (0.7, 0.0, 0.15), com=com, primitives=[Primitive("box", size)])


def test_symmetries_of_boxes_and_asymmetric_objects():
    assert len(yaw_symmetries(_box((0.4, 0.4, 0.3)))) == 4            # square footprint
    assert yaw_symmetries(_box((0.3, 0.4, 0.25))) == (0.0, math.pi)   # rectangle
    assert yaw_symmetries(_box((0.4, 0.4, 0.3), com=(0.05, 0.0, 0.0))) == (0.0,)   # off-centre mass
    handle = SceneObject("trolley", "trolley", True, (0, 0, 0),
                         primitives=[Primitive("box", (0.8, 0.5, 0.05)), Primitive("box", (0.04, 0.5, 0.04), (-0.45, 0, 0.5))])
    assert yaw_symmetries(handle) == (0.0,)


def test_the_stance_on_the_robots_side_costs_least():
    box = _box((0.4, 0.4, 0.3))
    feet = [LimbTarget("left_foot", np.array([0.7, 0.62, 0.0]), object_id="floor"),
            LimbTarget("right_foot", np.array([0.46, 0.62, 0.0]), object_id="floor")]   # beside the box, facing -y
    hands = [LimbTarget("left_hand", np.array([0.9, 0.0, 0.25]), np.array([1.0, 0, 0]), "box"),
             LimbTarget("right_hand", np.array([0.5, 0.0, 0.25]), np.array([-1.0, 0, 0]), "box")]
    fp = [footprint_of(box, box.position, box.rpy())]
    costs = {}
    for k in range(4):
        a = k * math.pi / 2
        cs = {t.limb: rotate_about(t, box.position, a) for t in feet + hands}
        costs[k] = stance_cost(cs, -math.pi / 2 + a, (0.0, 0.0), 0.0, fp, fp).total
    assert min(costs, key=costs.get) == 1     # turned by +90 deg: in front of the box, facing +x
    assert costs[3] > costs[1] + 1.0          # the far side: round the box and turned about


def test_a_placement_keeps_the_grasp_it_picked_with():
    grasp = {"left_hand": LimbTarget("left_hand", np.array([0.7, 0.2, 0.25]), np.array([0, 1.0, 0]), "box"),
             "right_hand": LimbTarget("right_hand", np.array([0.7, -0.2, 0.25]), np.array([0, -1.0, 0]), "box")}
    demo = [LimbTarget("left_hand", np.array([0.9, 0.0, 0.2]), np.array([1.0, 0, 0]), "box"),
            LimbTarget("right_hand", np.array([0.5, 0.0, 0.2]), np.array([-1.0, 0, 0]), "box")]
    cands = {k * math.pi / 2: {t.limb: rotate_about(t, (0.7, 0.0, 0.15), k * math.pi / 2) for t in demo}
             for k in range(4)}
    assert math.isclose(best_grasp_match(cands, grasp), math.pi / 2)
