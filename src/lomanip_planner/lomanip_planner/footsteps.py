"""Footholds of a two-foot walk: rounds of steps along a route, each one a step a G1 leg can make.

A walk goes from a stance to target feet along a route of the mid-feet point (lomanip_to.route).
Each foot follows its own path: the route point plus the foot's offset in the walking frame, the
offset blended from where it starts to where it ends, so a turning walk turns the stance with it
instead of sliding each foot in a straight line. The walk is cut into rounds (the leading foot
steps, then the other one comes level with it) at route fractions chosen so that every step stays
inside :class:`StepLimits` measured from the stance foot: how far ahead and aside, how much it
turns and how far it travels.

Why: the uniform rounds of session 52 and before put S1's first carrying step 0.47 m sideways of
the stance foot (the route leaves at 55 degrees while the feet still face forward); the TO then
crouched into a 0.42 m stance and the executed robot fell two steps later. S2's 90-degree turn
with straight-line feet put the left foot onto the right one's foothold. Simplification (named):
a greedy choice along one route with a fixed heading profile, not a footstep search over
footholds with costs (no terrain, no alternative routes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lomanip_to.route import TURN_MAX_ANGLE, TURN_MIN_ANGLE, point_along, route_length, smoothstep

FEET = ("left_foot", "right_foot")

#: m of route over which a walk that turns to face its way faces it (and turns to its end heading
#: over the same at its end): turning happens in the first small steps, nearly in place, as a
#: person turns before walking off, not while stepping sideways down the route
TURN_ROUTE = 0.15
#: route fractions tried per round (the largest feasible is taken)
CANDIDATES = 200
#: rounds at most in one walk (a walk that cannot be cut into feasible rounds ends with the
#: best effort; the TO's foothold squares and kinematics then decide)
MAX_ROUNDS = 16


@dataclass(frozen=True)
class StepLimits:
    """Where the swing foot's sole centre may land, in the stance foot's frame (heading along x).

    G1 values: the hip's reach and the legs' width (the TO's sole patch is 0.05-0.06 m wide,
    0.17 m long); the ``length`` is the schedule's ``max_step_length``."""

    forward: tuple[float, float] = (-0.12, 0.35)   # m along the stance foot
    lateral: tuple[float, float] = (0.16, 0.34)    # m across it, towards the swing foot's side
    turn: float = 0.6                              # rad between the two feet's headings
    length: float = 0.35                           # m the swing foot travels


#: a walk at least this long (m) whose way leaves the start or end heading by more than
#: TURN_MIN_ANGLE (and neither by TURN_MAX_ANGLE or more: no turning round) turns to face it first (lomanip_to.route.turns
#: asks 0.9 m of the TO's nominal; S2's carry, 0.6 m to the side, stepped sideways 7 cm at a time)
FACE_MIN_LENGTH = 0.4


def _faces_its_way(route: np.ndarray, yaw0: float, yaw1: float) -> bool:
    if route_length(route) < FACE_MIN_LENGTH:
        return False
    d = np.asarray(route[-1], float) - np.asarray(route[0], float)
    th = math.atan2(d[1], d[0])
    off = max(abs(math.remainder(th - yaw0, 2 * math.pi)), abs(math.remainder(th - yaw1, 2 * math.pi)))
    return TURN_MIN_ANGLE < off < TURN_MAX_ANGLE


def side_of(foot: str) -> float:
    return 1.0 if foot == "left_foot" else -1.0


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


class Walk:
    """Route, heading profile and the two feet's paths of one walk (fractions ``s`` in [0, 1])."""

    def __init__(self, route: np.ndarray, start: dict[str, np.ndarray], end: dict[str, np.ndarray],
                 yaw0: float, yaw1: float) -> None:
        self.route = np.asarray(route, float)
        self.yaw0 = float(yaw0)
        self.yaw1 = self.yaw0 + math.remainder(float(yaw1) - self.yaw0, 2 * math.pi)
        self.turning = _faces_its_way(self.route, self.yaw0, self.yaw1)
        self.length = route_length(self.route)
        a, b = self.route[0], self.route[-1]
        self.offset0 = {f: _rot(self.yaw0).T @ (np.asarray(start[f], float)[:2] - a) for f in FEET}
        self.offset1 = {f: _rot(self.yaw1).T @ (np.asarray(end[f], float)[:2] - b) for f in FEET}
        self.start = {f: np.asarray(start[f], float)[:2] for f in FEET}
        #: m: the narrower of the start and end stances (S1's box top: 0.14 m; steps keep 3 cm less)
        self.narrowest = min(float(np.linalg.norm(self.offset0[FEET[0]] - self.offset0[FEET[1]])),
                             float(np.linalg.norm(self.offset1[FEET[0]] - self.offset1[FEET[1]])))
        self.end = {f: np.asarray(end[f], float)[:2] for f in FEET}

    def heading(self, s: float) -> float:
        """Heading of the walking frame: a walk that turns faces its way after TURN_ROUTE of it and
        turns to the end heading over its last TURN_ROUTE; any other walk turns evenly."""
        if not self.turning:
            return (1.0 - s) * self.yaw0 + s * self.yaw1
        d = self.route[-1] - self.route[0]
        th = self.yaw0 + math.remainder(math.atan2(d[1], d[0]) - self.yaw0, 2 * math.pi)
        span = min(0.3, TURN_ROUTE / max(self.length, 1e-9))
        if s <= 0.5:
            return self.yaw0 + (th - self.yaw0) * smoothstep(s / span)
        return th + (self.yaw1 - th) * smoothstep((s - (1.0 - span)) / span)

    def foot(self, f: str, s: float) -> np.ndarray:
        """(x, y) of foot ``f`` at fraction ``s``: exactly its start at 0 and its target at 1."""
        if s <= 0.0:
            return self.start[f].copy()
        if s >= 1.0:
            return self.end[f].copy()
        off = (1.0 - s) * self.offset0[f] + s * self.offset1[f]
        return point_along(self.route, s) + _rot(self.heading(s)) @ off


def step_violation(stance_xy, stance_yaw: float, swing_from, swing_to, swing_yaw: float, side: float,
                   limits: StepLimits) -> float:
    """How far (m, rad) a step lies outside ``limits``; 0 when the leg can make it."""
    d = _rot(stance_yaw).T @ (np.asarray(swing_to, float)[:2] - np.asarray(stance_xy, float)[:2])
    fwd, lat = float(d[0]), side * float(d[1])
    v = max(0.0, limits.forward[0] - fwd) + max(0.0, fwd - limits.forward[1])
    v += max(0.0, limits.lateral[0] - lat) + max(0.0, lat - limits.lateral[1])
    v += max(0.0, abs(math.remainder(swing_yaw - stance_yaw, 2 * math.pi)) - limits.turn)
    v += max(0.0, float(np.linalg.norm(np.asarray(swing_to, float)[:2] - np.asarray(swing_from, float)[:2]))
             - limits.length)
    return v


def round_violation(walk: Walk, lead: str, s0: float, s1: float, limits: StepLimits) -> float:
    """Violation of one round: ``lead`` steps from s0 to s1 beside the other foot at s0, then the
    other foot comes to s1 beside it. In the last round (s1 = 1) only where the leading foot lands
    is checked: the feet end where the keyframe put them."""
    other = _other(lead)
    last = s1 >= 1.0 - 1e-12
    lateral = (min(limits.lateral[0], walk.narrowest - 0.03), limits.lateral[1])
    limits = StepLimits(limits.forward, lateral, limits.turn, limits.length)
    v = step_violation(walk.foot(other, s0), walk.heading(s0), walk.foot(lead, s0), walk.foot(lead, s1),
                       walk.heading(s1), side_of(lead), limits)
    if not last:
        v += step_violation(walk.foot(lead, s1), walk.heading(s1), walk.foot(other, s0), walk.foot(other, s1),
                            walk.heading(s1), side_of(other), limits)
    return v


def uniform_rounds(n: int) -> list[float]:
    return [i / n for i in range(1, n + 1)]


def _other(foot: str) -> str:
    return FEET[1] if foot == FEET[0] else FEET[0]


def _feasible(walk: Walk, rounds: list[tuple[float, str]], s0: float, limits: StepLimits) -> bool:
    bounds = [s0] + [s for s, _ in rounds]
    return all(round_violation(walk, lead, a, b, limits) <= 1e-9
               for a, b, (_, lead) in zip(bounds, bounds[1:], rounds))


def plan_rounds(walk: Walk, lead: str, limits: StepLimits, n_even: int) -> list[tuple[float, str]]:
    """(route fraction at the end of the round, the foot that leads it) for each round; the last
    fraction is 1.0.

    ``n_even`` even rounds led by ``lead`` are kept when every step in them is feasible (a
    straight walk: as before session 53). Else each round goes as far as its steps allow, led by
    the foot that gets further (turning right, the right foot opens the turn), and the full steps
    after the last short one are spread evenly."""
    even = [(s, lead) for s in uniform_rounds(max(1, n_even))]
    if _feasible(walk, even, 0.0, limits):
        return even
    out: list[tuple[float, str]] = []
    s_prev, last_lead = 0.0, _other(lead)
    while s_prev < 1.0 and len(out) < MAX_ROUNDS - 1:
        cand = s_prev + (1.0 - s_prev) * np.arange(1, CANDIDATES + 1) / CANDIDATES
        best = None
        for f in (_other(last_lead), last_lead):    # alternate feet when both get as far
            viol = np.array([round_violation(walk, f, s_prev, float(s), limits) for s in cand])
            ok = np.flatnonzero(viol <= 1e-9)
            if ok.size:
                key = (1, float(cand[ok[-1]]))
            else:   # none feasible: the least violation, making at least a tenth of the way left
                far = np.flatnonzero(cand >= s_prev + 0.1 * (1.0 - s_prev))
                j = far[int(np.argmin(viol[far] - 1e-6 * cand[far]))]
                key = (0, -float(viol[j]), float(cand[j]))
            if best is None or key > best[0]:
                best = (key, float(key[-1]), f)
        out.append((best[1], best[2]))
        s_prev, last_lead = best[1], best[2]
    if not out or out[-1][0] < 1.0:
        out.append((1.0, _other(last_lead)))
    return _even_out(walk, out, limits)


def _even_out(walk: Walk, rounds: list[tuple[float, str]], limits: StepLimits) -> list[tuple[float, str]]:
    """The greedy rounds from the earliest possible one on cut into equal rounds (same leads) when
    those stay feasible. Why: greedy left a last step of a few cm after full ones."""
    for i in range(len(rounds) - 1):
        s0 = rounds[i - 1][0] if i > 0 else 0.0
        n = len(rounds) - i
        tail = [(s0 + (1.0 - s0) * k / n, rounds[i + k - 1][1]) for k in range(1, n + 1)]
        if _feasible(walk, tail, s0, limits):
            return rounds[:i] + tail
    return rounds
