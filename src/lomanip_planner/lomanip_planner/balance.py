"""Static balance of a keyframe: where the robot's centre of mass, with the weight its hands hold,
falls in the support polygon of its feet.

Why a separate check: the retargeting's CoM task balances the robot alone (weight 1 against
100-1000 for the contacts), so a pick keyframe that keeps the demonstrator's stance can hold a box
at arm's length with the robot-and-box CoM past its toes. The TO must then start the carry from a
state no force distribution can hold (S2 from prompts, docs/planner_s1.md, sessions 33-34).
"""

from __future__ import annotations

import numpy as np


def _turn(o, a, b) -> float:
    """z of (a - o) x (b - o): > 0 for a left (counter-clockwise) turn."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2-D ``points`` (Andrew's monotone chain), without repeats."""
    pts = sorted({(float(x), float(y)) for x, y in np.asarray(points, float)[:, :2]})
    if len(pts) < 3:
        return np.asarray(pts, float)

    def half(seq):
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 0.0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.asarray(half(pts) + half(reversed(pts)), float)


def support_margin(point: np.ndarray, hull: np.ndarray) -> tuple[float, np.ndarray]:
    """(signed distance m, unit outward normal) of ``point`` to the polygon ``hull`` (counter-
    clockwise, at least 3 vertices): positive inside, the distance to the nearest edge; negative
    outside, by the edge it is farthest past (exact off the corners, a lower bound near them). The
    normal is that edge's: moving the polygon along it by d raises the margin by d."""
    p = np.asarray(point, float)[:2]
    if len(hull) < 3:
        raise ValueError("a support polygon needs at least 3 vertices")
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)   # outward for a counter-clockwise hull
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    outside = np.einsum("ij,ij->i", normals, p - hull)        # > 0: past that edge
    k = int(np.argmax(outside))
    return float(-outside[k]), normals[k]


def combined_com(robot_mass: float, robot_com: np.ndarray, load_mass: float = 0.0,
                 load_point: np.ndarray | None = None) -> np.ndarray:
    """Centre of mass of the robot and a point load (kg, world m)."""
    com = np.asarray(robot_com, float)
    if load_mass <= 0.0 or load_point is None:
        return com.copy()
    return (robot_mass * com + load_mass * np.asarray(load_point, float)) / (robot_mass + load_mass)
