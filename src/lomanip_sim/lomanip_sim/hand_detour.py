"""Hand position references shifted round static scene geometry that the dense plan sweeps through.

Why: the TO checks its hand spheres against the scene only at its knots (0.1-0.2 s apart) and
models the hand as a point, so between two knots the dense plan can sweep the sim's hand collision
box (13 x 7 x 11 cm) through a table edge. In S2 the right hand box goes from under the table top
(knot 1.8 s) to above it (knot 2.0 s), 96 mm inside the top at 1.90 s; tracked, the hand wedges
under the top with up to 300 N and the robot falls at 2.5 s.

Here, before execution, the hand box is placed at every reference pose of the dense grid and its
distance to every static scene geom (bodies welded to the world, planes excluded) is measured with
MuJoCo (``mj_geomDistance``). Each stretch where the reference goes into such a geom (clearance
< 0) is shifted by a smooth bump ``s(t) a u``: ``u`` one of 26 world directions, ``a`` and the ramp
time the gentlest (least extra acceleration) for which the whole shifted stretch, ramps included,
keeps ``margin`` and comes no closer to a movable object (at its planned pose) than the plan does.
Hand contact phases are never shifted. This is a geometric correction of the hand reference (a
named simplification of the executor), not a planned motion: the posture reference still follows
the plan's joints.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import mujoco
import numpy as np

_DIRECTIONS = np.array([d for d in product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
_DIRECTIONS = _DIRECTIONS / np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True)


@dataclass
class Detour:
    """One shifted stretch of a hand reference."""

    limb: str
    t_start: float  # s, first and last grid time inside an obstacle (before the shift)
    t_end: float
    depth: float  # m, deepest penetration of the original reference (negative clearance)
    direction: np.ndarray | None  # world unit vector; None: no shift found, reference left as planned
    amplitude: float = 0.0
    clearance: float = 0.0  # m, smallest clearance of the shifted stretch
    ramp: float = 0.0  # s, the shorter of the shift's ramps in and out


def static_obstacle_geoms(model: mujoco.MjModel, robot_root: int) -> list[int]:
    """Collidable, non-plane geoms of bodies welded to the world (tables, shelves), not the robot."""
    out = []
    for g in range(model.ngeom):
        b = model.geom_bodyid[g]
        if b == 0 or model.body_weldid[b] != 0 or model.body_rootid[b] == robot_root:
            continue
        collides = model.geom_contype[g] or model.geom_conaffinity[g]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE or not collides:
            continue
        out.append(g)
    return out


def movable_bodies(model: mujoco.MjModel, robot_root: int) -> list[int]:
    """Free-floating bodies of the scene (the objects a plan may move), not the robot."""
    return [b for b in range(1, model.nbody) if model.body_parentid[b] == 0 and b != robot_root
            and model.body_jntnum[b] == 1 and model.jnt_type[model.body_jntadr[b]] == mujoco.mjtJoint.mjJNT_FREE]


class HandBoxProbe:
    """Distance from a hand collision box, placed at a given site pose, to the scene's geoms.

    ``static``: geoms that never move. ``movable``: body id -> (N,3) positions and (N,4) wxyz
    quaternions of free bodies along the plan's grid (their geoms are placed there per sample).
    """

    def __init__(self, model: mujoco.MjModel, hand_geom: int, site_id: int, static: list[int],
                 movable: dict[int, tuple[np.ndarray, np.ndarray]] | None = None, distmax: float = 0.3):  # fmt: skip
        if model.geom_bodyid[hand_geom] != model.site_bodyid[site_id]:
            raise ValueError("hand geom and hand site must be on the same body")
        self.model, self.geom, self.static, self.distmax = model, hand_geom, list(static), distmax
        Rs = _quat_mat(model.site_quat[site_id])
        self._R_rel = Rs.T @ _quat_mat(model.geom_quat[hand_geom])  # geom orientation in the site frame
        self._p_rel = Rs.T @ (model.geom_pos[hand_geom] - model.site_pos[site_id])
        self._mov = []  # (geom, local pos, local rot, positions (N,3), rotations (N,3,3))
        for b, (P, Q) in (movable or {}).items():
            Rb = np.array([_quat_mat(q) for q in Q])
            for g in range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b]):
                if model.geom_contype[g] or model.geom_conaffinity[g]:
                    self._mov.append((g, model.geom_pos[g].copy(), _quat_mat(model.geom_quat[g]), np.asarray(P), Rb))
        self.data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, self.data)  # static geoms' poses do not depend on qpos
        self._fromto = np.zeros(6)

    def _min_dist(self, geoms) -> float:
        best = self.distmax
        for g in geoms:
            best = min(best, mujoco.mj_geomDistance(self.model, self.data, self.geom, g, self.distmax, self._fromto))
        return float(best)

    def clearance(self, p_site: np.ndarray, R_site: np.ndarray, i: int | None = None) -> tuple[float, float]:
        """(static, movable) smallest signed distances (m, negative = inside, capped at distmax) of the
        box at that site pose; movable objects at grid sample ``i`` (distmax when None or none)."""
        d = self.data
        d.geom_xpos[self.geom] = p_site + R_site @ self._p_rel
        d.geom_xmat[self.geom] = (R_site @ self._R_rel).reshape(-1)
        static = self._min_dist(self.static)
        if i is None or not self._mov:
            return static, self.distmax
        for g, pl, Rl, P, Rb in self._mov:
            d.geom_xpos[g] = P[i] + Rb[i] @ pl
            d.geom_xmat[g] = (Rb[i] @ Rl).reshape(-1)
        return static, self._min_dist([m[0] for m in self._mov])


class ObjectsAsObstacles:
    """A probe that counts the movable objects (at their planned poses) as obstacles too, for a
    :func:`detour` of a free hand round an object it is not yet touching."""

    def __init__(self, probe: HandBoxProbe):
        self.probe, self.distmax = probe, probe.distmax

    def clearance(self, p_site: np.ndarray, R_site: np.ndarray, i: int | None = None) -> tuple[float, float]:
        static, movable = self.probe.clearance(p_site, R_site, i)
        return min(static, movable), self.distmax


def _quat_mat(q) -> np.ndarray:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(q, float))
    return R.reshape(3, 3)


def _stretches(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    idx = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(idx[::2], idx[1::2])]


def _bump(t: np.ndarray, ta: float, tb: float, lo: float, hi: float) -> np.ndarray:
    """0 outside [lo, hi], 1 on [ta, tb], smoothstep ramps in between."""
    s = np.zeros_like(t)
    s[(t >= ta) & (t <= tb)] = 1.0
    for a, b, rising in ((lo, ta, True), (tb, hi, False)):
        sel = (t > a) & (t < b)
        if b > a and np.any(sel):
            u = (t[sel] - a) / (b - a)
            u = u if rising else 1.0 - u
            s[sel] = u * u * (3.0 - 2.0 * u)
    return s


def detour(limb: str, t: np.ndarray, pos: np.ndarray, rot: np.ndarray, in_contact: np.ndarray, probe: HandBoxProbe,
           margin: float = 0.02, pre_contact: float = 0.2, ramps=(0.6, 0.45, 0.3, 0.2),
           amplitudes=tuple(np.arange(0.02, 0.305, 0.02))) -> tuple[np.ndarray, list[Detour]]:  # fmt: skip
    """(shifted (N,3) positions, detours) for one hand's reference ``pos``/``rot`` on grid ``t``.

    A stretch is the run of samples inside a static geom; the shift is full over it and ramps in
    and out over up to ``ramp`` s, ending ``pre_contact`` s before a contact phase of the hand.
    Every sample of the shifted window must keep ``margin`` from static geoms (or, where the plan
    is already closer without going in, the plan's own clearance) and may come no closer to a
    movable object than the plan does. Among such shifts the gentlest is taken: smallest
    amplitude / (shortest ramp)^2, the hand's extra acceleration the body has to balance.
    """
    pos = np.array(pos, float)
    n = len(t)
    far = (probe.distmax, probe.distmax)
    base = [probe.clearance(pos[i], rot[i], i) if not in_contact[i] else far for i in range(n)]
    clear = np.array([c[0] for c in base])
    need_s = np.where(clear < 0.0, margin, np.minimum(clear, margin) - 1e-4)
    need_m = np.minimum(np.array([c[1] for c in base]), margin) - 1e-4
    contact_t = t[in_contact]
    out: list[Detour] = []
    for ia, ib in _stretches((clear < 0.0) & ~in_contact):
        depth = float(clear[ia : ib + 1].min())
        prev, nxt = contact_t[contact_t < t[ia]], contact_t[contact_t > t[ib]]
        t_lo = prev[-1] + 1e-9 if len(prev) else -np.inf  # ramps stay off contact phases
        t_hi = nxt[0] - pre_contact if len(nxt) else np.inf
        if t_hi <= t[ib]:
            out.append(Detour(limb, float(t[ia]), float(t[ib]), depth, None))
            continue
        best = None  # (cost, amplitude, direction, clearance, profile, ramp)
        for ramp in ramps:
            lo, hi = max(t[ia] - ramp, t_lo), min(t[ib] + ramp, t_hi)
            eff = max(float(min(t[ia] - lo, hi - t[ib])), 1e-3)  # a stretch right after a contact: no ramp in
            s = _bump(t, t[ia], t[ib], lo, hi)
            win = np.flatnonzero(s > 0)
            order = win[np.argsort(clear[win])]  # most penetrating samples first: early rejection
            for a in amplitudes:
                if best is not None and a / eff**2 >= best[0]:
                    break
                found = None
                for u in _DIRECTIONS:
                    worst = np.inf
                    for i in order:
                        cs, cm = probe.clearance(pos[i] + s[i] * a * u, rot[i], i)
                        if cs < need_s[i] or cm < need_m[i]:
                            worst = -np.inf
                            break
                        worst = min(worst, cs)
                    if worst > -np.inf and (found is None or worst > found[1]):
                        found = (u, worst)
                if found is not None:
                    best = (a / eff**2, float(a), found[0], float(found[1]), s, eff)
                    break
        rec = Detour(limb, float(t[ia]), float(t[ib]), depth, None)
        if best is not None:
            _c, a, u, worst, s, ramp = best
            pos += (s * a)[:, None] * u
            rec.direction, rec.amplitude, rec.clearance, rec.ramp = u, a, worst, ramp
        out.append(rec)
    return pos, out
