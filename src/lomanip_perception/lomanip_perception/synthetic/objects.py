"""Parametric object instances of the scene classes, for synthetic demonstrations.

Each builder returns primitives in the object frame with the same topology and frame origin as the
simulator's objects of that class (lomanip_sim.world), so canonical coordinates (bounding-box
normalised) mean the same part on both: box (origin at the centre), shelf and table (origin on
the floor under the top's centre), basket (origin at the bottom's centre), trolley (origin on the
floor, handle at local -x, pushing direction +x). Sizes are FULL bounding-box extents.
"""
from __future__ import annotations

import numpy as np
from lomanip_sim import frames

from ..scene import ObjectGeometry, Primitive

#: nominal full bounding-box sizes when the scene gives no reference instance
NOMINAL_SIZES = {"box": (0.40, 0.40, 0.30), "shelf": (0.40, 0.80, 1.50), "table": (0.60, 0.80, 0.70),
                 "basket": (0.30, 0.40, 0.25), "trolley": (0.80, 0.50, 0.866)}
CLASSES = tuple(NOMINAL_SIZES)
_Q_X90 = frames.axis_angle_to_quat([1, 0, 0], np.pi / 2)
_I = np.array([1.0, 0.0, 0.0, 0.0])


def _box(h, pos, rgba):
    return Primitive("box", tuple(float(x) for x in h), np.asarray(pos, float), _I.copy(), tuple(rgba))


def build_primitives(object_class: str, size, rgba) -> list[Primitive]:
    d, w, h = (float(x) for x in size)
    if object_class == "box":
        return [_box((d / 2, w / 2, h / 2), (0, 0, 0), rgba)]
    if object_class in ("shelf", "table"):
        top, leg = (0.03, 0.04) if object_class == "shelf" else (0.04, 0.05)
        prims = [_box((d / 2, w / 2, top / 2), (0, 0, h - top / 2), rgba)]
        leg_h = (h - top) / 2
        for sx, sy in [(1, 1), (1, -1), (-1, 1), (-1, -1)]:
            prims.append(_box((leg / 2, leg / 2, leg_h), (sx * (d / 2 - leg / 2), sy * (w / 2 - leg / 2), leg_h), rgba))
        if object_class == "shelf":
            prims.append(_box((d / 2 - leg, w / 2 - leg, top / 2), (0, 0, h / 2), rgba))
        return prims
    if object_class == "basket":
        t = min(0.01, 0.25 * min(d, w, h))
        hw = (h - t) / 2
        return [_box((d / 2, w / 2, t / 2), (0, 0, t / 2), rgba),
                _box((t / 2, w / 2, hw), (-d / 2 + t / 2, 0, t + hw), rgba),
                _box((t / 2, w / 2, hw), (d / 2 - t / 2, 0, t + hw), rgba),
                _box((d / 2 - t, t / 2, hw), (0, w / 2 - t / 2, t + hw), rgba),
                _box((d / 2 - t, t / 2, hw), (0, -w / 2 + t / 2, t + hw), rgba)]
    if object_class == "trolley":
        L, W = d, w
        bar_r, post_r = 0.016, 0.015
        handle = h - bar_r
        deck = 0.41 * handle
        r = min(0.06, 0.3 * deck)
        t = 0.03
        wy = W / 2 - 0.04
        x_handle = -L / 2 + post_r
        post_half = (handle - deck) / 2
        dark = (0.1, 0.1, 0.1, 1.0)
        prims = [_box((L / 2, W / 2, t / 2), (0, 0, deck - t / 2), rgba),
                 Primitive("cylinder", (post_r, post_half), np.array([x_handle, wy, deck + post_half]), _I.copy(), tuple(rgba)),
                 Primitive("cylinder", (post_r, post_half), np.array([x_handle, -wy, deck + post_half]), _I.copy(), tuple(rgba)),
                 Primitive("cylinder", (bar_r, wy + post_r), np.array([x_handle, 0, handle]), _Q_X90.copy(), tuple(rgba))]
        leg_half = (deck - t - r) / 2
        for x in (-L / 2 + 0.10, L / 2 - 0.10):
            for y in (wy, -wy):
                prims.append(_box((0.012, 0.012, leg_half), (x, y, r + leg_half), rgba))
                prims.append(Primitive("cylinder", (r, 0.02), np.array([x - (0.04 if x > 0 else 0.0), y, r]), _Q_X90.copy(), dark))
        return prims
    raise ValueError(f"no synthetic instance builder for class {object_class!r}; known: {', '.join(CLASSES)}")


def make_object(name: str, object_class: str, size, rgba, pos, yaw: float) -> ObjectGeometry:
    return ObjectGeometry(name, object_class, np.asarray(pos, float), frames.yaw_to_quat(yaw),
                          tuple(build_primitives(object_class, size, rgba)))


def top_height_local(obj: ObjectGeometry) -> float:
    """Height of the supporting top surface above the object frame origin (for stacking)."""
    c, h = obj.bbox_local()
    if obj.object_class == "trolley":
        return float(obj.primitives[0].pos[2] + obj.primitives[0].size[2])
    return float(c[2] + h[2])


def bottom_offset(obj_class: str, size) -> float:
    """Height of the object frame origin above its lowest point."""
    return float(size[2]) / 2.0 if obj_class == "box" else 0.0


def palette(rng: np.random.Generator, avoid=None) -> tuple[float, float, float, float]:
    """A random saturated colour (not too close to ``avoid``)."""
    for _ in range(20):
        hsv = (rng.uniform(0, 1), rng.uniform(0.35, 0.85), rng.uniform(0.45, 0.9))
        rgb = _hsv_to_rgb(*hsv)
        if avoid is None or np.linalg.norm(np.asarray(rgb) - np.asarray(avoid[:3])) > 0.25:
            return (*rgb, 1.0)
    return (*rgb, 1.0)


def _hsv_to_rgb(h, s, v):
    i = int(h * 6) % 6
    f = h * 6 - int(h * 6)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    return [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i]
