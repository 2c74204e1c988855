"""Base routes on the floor that go round objects instead of through them.

Why: the keyframe nominal moved the base in a straight line between keyframes, so walking from the
trolley's side to its handle (S2 subtask 2) or away from the table (subtask 1) led the warm start,
and the walking stage cost that tracks it, through furniture; the TO then had to find the way
round on its own and mostly did not (guide stage at its iteration cap).  Here every object the
robot is not holding or standing on is an oriented rectangle on the floor (its primitives'
footprint), grown by a clearance, and the route is the shortest path round them: a visibility
graph over the grown rectangles' corners, searched with Dijkstra.  Named simplification: the
footprint is the bounding rectangle of the whole object in its own frame, so the robot never
plans to walk under a table, and the route is a polyline (corners are not rounded).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

#: clearance between the base path and an object's footprint (m): the G1's half shoulder width
#: with the arms at its sides is ~0.2 m, plus a margin for the swinging feet
ROUTE_CLEARANCE = 0.30
_EPS = 1e-6


@dataclass(frozen=True)
class Footprint:
    """An oriented rectangle on the floor: centre (x, y), yaw, half sizes (along its x, y)."""

    centre: tuple
    yaw: float
    half: tuple
    name: str = ""

    def _local(self, pts: np.ndarray) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        d = np.atleast_2d(pts) - np.asarray(self.centre)
        return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)

    def distance(self, pt) -> float:
        """Distance of a point to the rectangle (0 inside)."""
        q = np.abs(self._local(np.asarray(pt, float)[:2])[0]) - np.asarray(self.half)
        return float(np.linalg.norm(np.maximum(q, 0.0)))

    def corners(self, grow: float) -> np.ndarray:
        hx, hy = self.half[0] + grow, self.half[1] + grow
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        loc = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        return np.asarray(self.centre) + loc @ np.array([[c, s], [-s, c]])

    def blocks(self, a, b, grow: float) -> bool:
        """Whether the segment a-b passes through the interior of the grown rectangle
        (Liang-Barsky clipping in the rectangle's frame)."""
        pa, pb = self._local(np.asarray(a, float)[:2])[0], self._local(np.asarray(b, float)[:2])[0]
        d = pb - pa
        lo, hi = 0.0, 1.0
        for i in range(2):
            h = self.half[i] + grow - _EPS
            if abs(d[i]) < 1e-12:
                if abs(pa[i]) >= h:
                    return False
                continue
            t0, t1 = (-h - pa[i]) / d[i], (h - pa[i]) / d[i]
            if t0 > t1:
                t0, t1 = t1, t0
            lo, hi = max(lo, t0), min(hi, t1)
            if lo >= hi:
                return False
        return (hi - lo) * float(np.linalg.norm(d)) > 1e-4


def footprint_of(obj, position, rpy) -> Footprint:
    """The bounding rectangle, in the object's own yaw frame, of its primitives' floor footprints."""
    yaw = float(rpy[2])
    c, s = math.cos(yaw), math.sin(yaw)
    Rz = np.array([[c, -s], [s, c]])
    pts = []
    for pr in obj.primitives:
        he = np.asarray(pr.half_extents(), float)
        cp, sp = math.cos(pr.yaw), math.sin(pr.yaw)
        Rl = np.array([[cp, -sp], [sp, cp]])
        for sx in (-1, 1):
            for sy in (-1, 1):
                pts.append(np.asarray(pr.position, float)[:2] + Rl @ np.array([sx * he[0], sy * he[1]]))
    pts = np.array(pts)  # object frame
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = np.asarray(position, float)[:2] + Rz @ (0.5 * (lo + hi))
    return Footprint(tuple(centre), yaw, tuple(0.5 * (hi - lo)), getattr(obj, "id", ""))


def shortest_route(a, b, obstacles: list[Footprint], clearance: float = ROUTE_CLEARANCE) -> np.ndarray:
    """M x 2 polyline from a to b keeping ``clearance`` from every footprint.

    An obstacle closer than the clearance to a or b (the robot starts or ends next to it, e.g.
    at a table it picks from) gets a clearance of 90 % of that distance; one that contains a or b
    is left out.  Without a way round (b enclosed) the straight line is returned.
    """
    a, b = np.asarray(a, float)[:2], np.asarray(b, float)[:2]
    obs = []
    for fp in obstacles:
        d = min(fp.distance(a), fp.distance(b))
        if d <= _EPS:
            continue
        obs.append((fp, min(clearance, 0.9 * d)))
    if not any(fp.blocks(a, b, g) for fp, g in obs):
        return np.stack([a, b])
    nodes = [a, b]
    for fp, g in obs:
        for c in fp.corners(g + 1e-3):
            if not any(o.distance(c) < go for o, go in obs):
                nodes.append(c)
    n = len(nodes)

    def free(i: int, j: int) -> bool:
        return not any(fp.blocks(nodes[i], nodes[j], g) for fp, g in obs)

    dist = [math.inf] * n
    prev = [-1] * n
    dist[0] = 0.0
    heap = [(0.0, 0)]
    while heap:
        d, i = heapq.heappop(heap)
        if d > dist[i]:
            continue
        if i == 1:
            break
        for j in range(1, n):
            if j == i:
                continue
            nd = d + float(np.linalg.norm(nodes[j] - nodes[i]))
            if nd < dist[j] and free(i, j):
                dist[j], prev[j] = nd, i
                heapq.heappush(heap, (nd, j))
    if prev[1] < 0:
        return np.stack([a, b])
    path, i = [], 1
    while i >= 0:
        path.append(nodes[i])
        i = prev[i]
    return np.array(path[::-1])


def route_length(route: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum())


def point_along(route: np.ndarray, s: float) -> np.ndarray:
    """The point at fraction ``s`` (0..1) of the polyline's length."""
    seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
    total = float(seg.sum())
    if total < 1e-12:
        return route[0].copy()
    target = min(max(s, 0.0), 1.0) * total
    for i, L in enumerate(seg):
        if target <= L or i == len(seg) - 1:
            return route[i] + (route[i + 1] - route[i]) * (min(target, L) / max(L, 1e-12))
        target -= L
    return route[-1].copy()


#: a walk of at least this length (m) whose travel direction is more than TURN_MIN_ANGLE (rad) off
#: the heading at its start or end turns towards the travel direction and walks forwards; up to
#: TURN_MAX_ANGLE (further round, a turn costs more than it saves). Why: S1's carry went 1.25 m at 53
#: degrees off the robot's heading, so the plans crab-walked with 0.25 m side steps, rolled the
#: pelvis 0.4-0.8 rad and swung the left thigh into the box (docs/to.md, session 21)
TURN_MIN_LENGTH = 0.9
TURN_MIN_ANGLE = 0.5
TURN_MAX_ANGLE = 2.0
#: fraction of the walk over which the heading turns to the travel direction (and, at the end,
#: from it to the final heading)
TURN_SPAN = 0.4


def smoothstep(u: float) -> float:
    """0 below 0, 1 above 1, 3u^2 - 2u^3 between: a blend that starts and ends at rest."""
    u = min(1.0, max(0.0, u))
    return u * u * (3.0 - 2.0 * u)


def turns(route: np.ndarray, yaw0: float, yaw1: float) -> bool:
    """Whether a walk along ``route`` from heading ``yaw0`` to ``yaw1`` turns to walk forwards."""
    if route_length(route) < TURN_MIN_LENGTH:
        return False
    d = np.asarray(route[-1], float) - np.asarray(route[0], float)
    th = math.atan2(d[1], d[0])
    off = (abs(math.remainder(th - yaw0, 2 * math.pi)), abs(math.remainder(th - yaw1, 2 * math.pi)))
    return max(off) > TURN_MIN_ANGLE and max(off) < TURN_MAX_ANGLE


def walking_heading(route: np.ndarray, s: float, yaw0: float, yaw1: float) -> float:
    """Base heading at fraction ``s`` of a walk along ``route`` from heading ``yaw0`` to ``yaw1``.

    A walk that :func:`turns` faces its travel direction (the chord of the route) after the first
    TURN_SPAN of its length and turns to ``yaw1`` over the last (smoothsteps); any other walk
    interpolates the two headings linearly."""
    if not turns(route, yaw0, yaw1):
        return (1.0 - s) * yaw0 + s * yaw1
    d = np.asarray(route[-1], float) - np.asarray(route[0], float)
    th = yaw0 + math.remainder(math.atan2(d[1], d[0]) - yaw0, 2 * math.pi)
    if abs(th + math.remainder(yaw1 - th, 2 * math.pi) - yaw1) > 1e-9:  # yaw1 a turn or more away
        return (1.0 - s) * yaw0 + s * yaw1
    if s <= 1.0 - TURN_SPAN:
        return yaw0 + (th - yaw0) * smoothstep(s / TURN_SPAN)
    return th + (yaw1 - th) * smoothstep((s - (1.0 - TURN_SPAN)) / TURN_SPAN)
