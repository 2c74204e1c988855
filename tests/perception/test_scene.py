"""Object geometry: signed distance, closest-surface projection, canonical coordinates."""
from __future__ import annotations

import numpy as np

from lomanip_perception.scene import ObjectGeometry, Primitive
from lomanip_perception.synthetic.objects import make_object
from lomanip_sim import frames


def _box(yaw=0.3):
    return ObjectGeometry("box", "box", np.array([1.0, 0.5, 0.15]), frames.yaw_to_quat(yaw),
                          (Primitive("box", (0.2, 0.15, 0.15)),))


def test_box_signed_distance_and_projection():
    b = _box(0.0)
    pts = np.array([[1.5, 0.5, 0.15], [1.0, 0.5, 0.15], [1.0, 0.5, 0.5], [1.1, 0.5, 0.15]])
    sd, cp, n = b.signed_distance(pts)
    assert np.allclose(sd, [0.3, -0.15, 0.2, -0.1])
    assert np.allclose(cp[0], [1.2, 0.5, 0.15]) and np.allclose(n[0], [1, 0, 0])
    assert np.allclose(cp[2], [1.0, 0.5, 0.3]) and np.allclose(n[2], [0, 0, 1])
    assert np.allclose(cp[3], [1.2, 0.5, 0.15]) and np.allclose(n[3], [1, 0, 0])  # inside: nearest face


def test_projection_lands_on_the_surface_of_a_rotated_object():
    b = _box(0.8)
    p = np.random.default_rng(0).normal(b.pos, 0.3, (200, 3))
    cp, n = b.project_to_surface(p)
    sd, _, _ = b.signed_distance(cp)
    assert np.max(np.abs(sd)) < 1e-9 and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    # each projected point is the closest of many surface samples (up to sampling resolution)
    surf = b.sample_surface(0.01)
    d_proj = np.linalg.norm(cp - p, axis=1)
    d_best = np.min(np.linalg.norm(p[:, None] - surf[None], axis=2), axis=1)
    assert np.all(d_proj <= d_best + 1e-9)


def test_union_of_primitives_cylinders_and_canonical_round_trip():
    trolley = make_object("trolley", "trolley", (0.8, 0.5, 0.9), (0.2, 0.3, 0.8, 1.0), (0.5, -1.0, 0.0), 0.4)
    bar = trolley.primitives[3]
    assert bar.type == "cylinder"
    p_on_bar = trolley.to_world(bar.pos + bar.R @ np.array([0.0, 0.0, 0.1]) + np.array([0, 0, bar.size[0]]))
    sd, _, _ = trolley.signed_distance(p_on_bar)
    assert abs(sd[0]) < 1e-6
    inside = trolley.to_world(trolley.primitives[0].pos)
    assert trolley.signed_distance(inside)[0][0] < 0
    c = np.random.default_rng(2).uniform(-1, 1, (20, 3))
    assert np.allclose(trolley.canonical(trolley.from_canonical(c)), c)
    _, h = trolley.bbox_local()
    assert np.allclose(2 * h, (0.8, 0.5, 0.9), atol=0.005)
    s = trolley.sample_surface(0.02)
    assert len(s) > 500 and np.max(np.abs(trolley.signed_distance(s)[0])) < 1e-3


def _basket():
    """A 30 x 40 x 25 cm basket: a bottom and four 1 cm walls, the frame at its bottom centre."""
    wall = 0.005
    prims = (Primitive("box", (0.15, 0.2, wall), np.array([0.0, 0.0, wall])),
             Primitive("box", (wall, 0.2, 0.125), np.array([-0.15 + wall, 0.0, 0.125])),
             Primitive("box", (wall, 0.2, 0.125), np.array([0.15 - wall, 0.0, 0.125])),
             Primitive("box", (0.15, wall, 0.125), np.array([0.0, -0.2 + wall, 0.125])),
             Primitive("box", (0.15, wall, 0.125), np.array([0.0, 0.2 - wall, 0.125])))
    return ObjectGeometry("basket", "basket", np.array([1.0, 0.0, 1.0]), frames.yaw_to_quat(0.0), prims)


def test_a_hand_point_deep_in_a_thin_wall_goes_to_the_face_its_elbow_is_on():
    basket = _basket()
    # 7 mm past the left wall's inner face (y = 0.19), the elbow outside the basket to the left
    hand = np.array([[0.95, 0.183, 1.2]])
    elbow = np.array([[0.7, 0.35, 1.05]])
    c, n = basket.project_to_surface(hand)
    assert np.allclose(n[0], [0, -1, 0]) and np.isclose(c[0, 1], 0.19)   # the closest: the inner face
    c, n = basket.project_to_surface_facing(hand, elbow)
    assert np.allclose(n[0], [0, 1, 0]) and np.allclose(c[0], [0.95, 0.2, 1.2])   # the outer face
    # an elbow inside the basket keeps the inner face (a hand hooked over the rim)
    c, n = basket.project_to_surface_facing(hand, np.array([[1.0, 0.0, 1.3]]))
    assert np.allclose(n[0], [0, -1, 0])
    # a facing face farther than the detour allows is not taken
    c, n = basket.project_to_surface_facing(hand, elbow, max_detour=0.005)
    assert np.allclose(n[0], [0, -1, 0])


def test_facing_projection_keeps_the_closest_surface_when_it_faces_the_elbow():
    b = _box(0.8)
    p = np.random.default_rng(1).normal(b.pos, 0.3, (50, 3))
    toward = b.pos + 3.0 * (p - b.pos)     # each point's elbow farther out along the same ray
    c0, n0 = b.project_to_surface(p)
    c1, n1 = b.project_to_surface_facing(p, toward)
    sd, _, _ = b.signed_distance(c1)
    assert np.max(np.abs(sd)) < 1e-9
    faced = np.einsum("ij,ij->i", n0, toward - c0) > 0
    assert faced.sum() > 25 and np.allclose(c1[faced], c0[faced]) and np.allclose(n1[faced], n0[faced])
