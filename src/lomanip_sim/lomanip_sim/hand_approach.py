"""A hand's approach to a contact kept outside the object it is about to touch.

Why: the TO checks a hand against an object only from the knot after the contact starts (its
hand-vs-object pairs are off one knot before), and it models the hand as a point. In the push of
``make demo`` the dense plan brings both hand boxes up through the trolley's handle bar and the
left one through its post (up to 62 mm inside, 2.2-2.5 s) to grasp the bar from behind and above
at 2.6 s; tracked, the hands hit the bar from below and in front with up to 1.7 kN (40 ms means)
and the trolley and the robot were shoved about.

Here, over a window before each contact of a hand, the hand reference (grasp offsets included) is
lifted along the contact normal, i.e. out of the object's face the hand will touch, by the
smallest distance that keeps the hand box ``margin`` from the scene (static geoms and the movable
objects at their planned poses, measured with MuJoCo). The lifts are spread with a smooth kernel
(no velocity steps) and taper to zero just before the contact, so the hand lands along the normal.
A geometric correction of the reference, like the grasp offsets; the plan's joints are unchanged.
"""

from __future__ import annotations

import numpy as np

from .hand_detour import HandBoxProbe


def smoothstep(u: np.ndarray) -> np.ndarray:
    """C1 ramp, 0 below 0 and 1 above 1: no velocity step where a ramp starts or ends."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _envelope(t: np.ndarray, need: np.ndarray, spread: float, start: float, post: float, taper: float) -> np.ndarray:
    """Max of need x smoothstep kernels; after the last lifted sample a smoothstep down to 0."""
    lift = np.zeros(len(t))
    hits = np.flatnonzero(need > 0)
    for i in hits:
        lift = np.maximum(lift, need[i] * smoothstep(1.0 - np.abs(t - t[i]) / spread))
    if len(hits):  # down to 0 at start + post (at least ``taper`` s after the last lifted sample)
        tl = t[hits[-1]]
        end = max(start + post, tl + taper)
        after = t > tl
        lift[after] = lift[hits[-1]] * smoothstep((end - t[after]) / (end - tl))
    return lift


def approach_lift(t: np.ndarray, pos: np.ndarray, rot: np.ndarray, normals: np.ndarray, start: float,
                  probe: HandBoxProbe, window: float = 0.8, margin: float = 0.01, spread: float = 0.2, last: float = 0.1,
                  taper: float = 0.1, step: float = 0.01, max_lift: float = 0.25, post: float = 0.0,
                  least_bad: bool = False) -> np.ndarray:  # fmt: skip
    """(N,) lift (m) along ``normals`` (N,3) for the approach to a contact starting at ``start``.

    Samples in [start - window, start - last) get the least lift (``step`` grid, up to ``max_lift``)
    whose hand box keeps ``margin`` from movable objects and from static geoms (or the plan's own
    clearance there, when smaller); the result is the max over samples of lift x a smoothstep
    kernel of half-width ``spread`` s up to the last lifted sample, then a smoothstep down to 0 at
    ``post`` s after the contact starts (at least ``taper`` s long): a hand lands softly, along the
    normal, where the plan's force is still small. Where no lift up to ``max_lift`` is clear, a sample
    gets ``max_lift``, or with ``least_bad`` the lift (0 included) whose clearance falls least short:
    S2's hands, letting go of the box on the trolley's deck, found no clear lift along the
    box's faces, and the full 25 cm drove the right wrist into the trolley's post.
    """
    idx = np.flatnonzero((t >= start - window) & (t < start - last))
    need_s = {i: min(probe.clearance(pos[i], rot[i], i)[0], margin) - 1e-4 for i in idx}

    def score(i: int, e: float) -> float:  # >= 0: clear
        s, m = probe.clearance(pos[i] + e * normals[i], rot[i], i)
        return min(m - margin, s - need_s[i])

    def ok(i: int, e: float) -> bool:
        return score(i, e) >= 0.0

    def fallback(i: int) -> float:
        if not least_bad:
            return max_lift
        lifts = np.arange(0.0, max_lift + 1e-9, step)
        return float(lifts[int(np.argmax([score(i, e) for e in lifts]))])

    need = np.zeros(len(t))
    lift = np.zeros(len(t))
    for _round in range(6):  # a neighbour's lift can carry a clear sample into the object: repeat
        bad = [i for i in idx if not ok(i, lift[i])]
        if not bad:
            break
        for i in bad:
            found = next((e for e in np.arange(lift[i] + step, max_lift + 1e-9, step) if ok(i, e)), None)
            need[i] = found if found is not None else fallback(i)
        lift = _envelope(t, need, spread, start, post, taper)
    return lift


class _ReversedProbe:
    """A probe whose grid index runs backwards (for a time-reversed grid)."""

    def __init__(self, probe: HandBoxProbe, n: int):
        self.probe, self.n = probe, n

    def clearance(self, p_site: np.ndarray, R_site: np.ndarray, i: int | None = None) -> tuple[float, float]:
        return self.probe.clearance(p_site, R_site, None if i is None else self.n - 1 - i)


def retreat_lift(t: np.ndarray, pos: np.ndarray, rot: np.ndarray, normals: np.ndarray, end: float,
                 probe: HandBoxProbe, **kwargs) -> np.ndarray:  # fmt: skip
    """(N,) lift (m) along ``normals`` for the hand's leave from a contact ending at ``end``.

    The approach in reverse time: samples in (end + last, end + window] get the least lift that
    keeps the hand box ``margin`` from the scene, spread smoothly; with ``taper`` <= ``last`` and
    ``post`` 0 it rises from 0 at ``end`` (nothing while the contact lasts), so the hand leaves along
    the normal. Why: the TO's hand is a point, free to sweep through the
    object once the contact ends; in the push of ``make demo`` the plan lowers both hands 20 cm
    straight through the trolley's handle bar after letting go, the hand boxes stayed on the bar
    pressing 10-35 N on it for 1.8 s and the robot fell backwards when they slipped off.
    """
    n = len(t)
    lift = approach_lift(-t[::-1], pos[::-1], rot[::-1], normals[::-1], -end, _ReversedProbe(probe, n), **kwargs)
    return lift[::-1].copy()
