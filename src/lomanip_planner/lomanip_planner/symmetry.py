"""Which of an object's symmetric equivalents of a demonstration the robot should use.

Why: a box looks the same from each of its sides, so neither the demonstration (the generator,
like an image model, shows a person at whichever side it likes) nor the contact transfer (ICP on a
symmetric shape) can say from which side of the scene's box the person works: the transferred
stance is right only up to the box's symmetry. Taken as it came, S1's pick walked the G1 round the
box to its far side and its place put the G1 beside the shelf (docs/planner_s1.md). Every
symmetric image of a demonstration is an equally valid reading of it, so the planner picks the
one that suits the robot: feet clear of objects, the shortest walk and turn from where the robot
stands, facing the hands. The same holds for a placement goal's yaw: a square box placed at yaw 0
or pi/2 is the same placement, and the robot, which keeps its grip while carrying, should turn the
box as little as the goal allows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lomanip_to.problem import SceneObject
from lomanip_to.route import Footprint, route_length, shortest_route

from .retargeting import FEET, HANDS, LimbTarget

#: added to a candidate whose floor foot is within FOOT_CLEARANCE of an object's footprint (m)
BLOCKED_COST = 10.0
#: half the G1 sole's width plus a margin (m)
FOOT_CLEARANCE = 0.08
#: metres of walking one radian of turning is worth
TURN_COST = 0.3
#: metres of walking one radian between the heading and the direction to the hands is worth
FACE_COST = 0.5


def _rect(kind: str, size, position, yaw: float) -> tuple:
    """A primitive as a canonical (kind, centre x, y, z, yaw mod pi/2, half sizes) key."""
    if kind == "box":
        hx, hy, hz = 0.5 * np.asarray(size, float)
    else:   # cylinder: (height, radius), round about its own axis
        h, r = size
        hx, hy, hz, yaw = r, r, 0.5 * h, 0.0
    y = math.remainder(yaw, math.pi / 2)            # in [-pi/4, pi/4]
    if round((yaw - y) / (math.pi / 2)) % 2:          # an odd number of quarter turns swaps x and y
        hx, hy = hy, hx
    return kind, np.array([*np.asarray(position, float), y, hx, hy, hz])


def yaw_symmetries(obj: SceneObject, tol: float = 0.01) -> tuple[float, ...]:
    """Rotations about the object's vertical axis through its origin (0, pi/2, pi, 3 pi/2) that map
    its primitives and its centre of mass onto themselves; (0.0,) for an object without any."""
    prims = list(obj.primitives)
    if not prims:
        return (0.0,)
    keys = [_rect(p.kind, p.size, p.position, p.yaw) for p in prims]
    out = [0.0]
    for k in (1, 2, 3):
        a = k * math.pi / 2
        c, s = math.cos(a), math.sin(a)
        com = np.asarray(obj.com, float)
        if np.linalg.norm([c * com[0] - s * com[1] - com[0], s * com[0] + c * com[1] - com[1]]) > tol:
            continue
        ok = True
        for p in prims:
            x, y, z = p.position
            kind, v = _rect(p.kind, p.size, (c * x - s * y, s * x + c * y, z), p.yaw + a)
            if not any(kind == k2 and np.all(np.abs(v - v2) <= tol) for k2, v2 in keys):
                ok = False
                break
        if ok:
            out.append(a)
    return tuple(out)


def rotate_about(t: LimbTarget, centre, angle: float) -> LimbTarget:
    """The contact turned by ``angle`` about the vertical axis through ``centre``."""
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    o = np.asarray(centre, float)
    p = o + R @ (np.asarray(t.position, float) - o)
    p[2] = t.position[2]
    return LimbTarget(t.limb, p, R @ np.asarray(t.normal, float), t.object_id)


def stance_yaw(left, right) -> float:
    """Heading of a stance (perpendicular to right -> left foot)."""
    lat = np.asarray(left, float)[:2] - np.asarray(right, float)[:2]
    return math.atan2(lat[1], lat[0]) - math.pi / 2


@dataclass(frozen=True)
class StanceCost:
    """Why a candidate costs what it does (for logs and tests)."""

    blocked: bool
    walk: float
    turn: float
    facing: float

    @property
    def total(self) -> float:
        return BLOCKED_COST * self.blocked + self.walk + TURN_COST * self.turn + FACE_COST * self.facing


def stance_cost(contacts: dict[str, LimbTarget], base_yaw: float | None, current_mid, current_yaw: float,
                obstacles: list[Footprint], route_obstacles: list[Footprint]) -> StanceCost:
    """How well a keyframe's contacts (world frame) suit a robot standing at ``current_mid`` facing
    ``current_yaw``: floor feet clear of ``obstacles``, the mid-feet route round ``route_obstacles``,
    the turn, and the angle between the heading and the hands."""
    feet = [contacts[f] for f in FEET if f in contacts]
    if not feet:
        return StanceCost(False, 0.0, 0.0, 0.0)
    floor_feet = [t for t in feet if t.object_id in ("", "floor")]
    blocked = any(fp.distance(t.position) < FOOT_CLEARANCE for t in floor_feet for fp in obstacles)
    mid = np.mean([t.position for t in feet], axis=0)
    walk = route_length(shortest_route(np.asarray(current_mid, float)[:2], mid[:2], route_obstacles))
    if base_yaw is None:
        base_yaw = stance_yaw(contacts["left_foot"].position, contacts["right_foot"].position) \
            if len(feet) == 2 else current_yaw
    turn = abs(math.remainder(base_yaw - current_yaw, 2 * math.pi))
    facing = 0.0
    hands = [contacts[h].position for h in HANDS if h in contacts]
    if hands:
        d = np.mean(hands, axis=0)[:2] - mid[:2]
        if np.linalg.norm(d) > 0.05:
            facing = abs(math.remainder(math.atan2(d[1], d[0]) - base_yaw, 2 * math.pi))
    return StanceCost(bool(blocked), float(walk), float(turn), float(facing))


def best_grasp_match(candidates: dict[float, dict[str, LimbTarget]], grasp: dict[str, LimbTarget]) -> float:
    """The symmetry angle whose hand contacts lie closest to a held ``grasp`` (same frame)."""
    def mismatch(cs: dict[str, LimbTarget]) -> float:
        common = [h for h in HANDS if h in cs and h in grasp]
        if not common:
            return 0.0
        return float(sum(np.linalg.norm(np.asarray(cs[h].position) - np.asarray(grasp[h].position)) for h in common))
    return min(candidates, key=lambda a: (mismatch(candidates[a]), abs(math.remainder(a, 2 * math.pi))))
