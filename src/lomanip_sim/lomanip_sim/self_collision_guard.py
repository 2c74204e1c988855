"""Rows that keep pairs of the G1's own links from pressing into each other: a control barrier on
their mesh distance, as inequalities on the whole-body QP's accelerations.

Why: the plan keeps the hip roll 0.04 rad inside the hip-roll link's contact with the pelvis
(lomanip_to.hip_coupling), which is 1-2 mm of clearance on MuJoCo's meshes in a deep squat. Any
tracking error closes it, and nothing in the controller's tasks knows the links are there: in S1's
lift from prompts the pelvis then pressed on the right hip-roll link with up to 1.4 kN and the
robot fell (docs/execution.md, session 54). For each guarded pair whose distance d is under
``activation`` the QP gets

    n^T (J_b - J_a) qdd >= -2 rate d_dot - rate^2 (d - min_distance)

(d_dot = n^T (J_b - J_a) qd; n the unit direction that separates b from a; the J_dot qd term is
left out), the second-order barrier under which d stays above ``min_distance`` when the row holds.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .robot_model import HAND_BODIES

#: the link pairs the G1's meshes let touch across a joint that the TO bounds in joint space only
HIP_PAIRS: tuple[tuple[str, str], ...] = tuple(
    ("pelvis", f"{side}_{link}_link") for side in ("left", "right") for link in ("hip_roll", "hip_yaw"))

#: each hand (the wrist-yaw link: the sim's 13 x 7 x 11 cm hand box and the wrist mesh) against its
#: own side's hip links and knee. The TO models the hand as two 4 cm spheres, which the box's edges
#: overhang by up to 2.3 cm: the demo push's 8 layout plans all hang a hand box 1.4-3.0 cm inside
#: a hip link on MuJoCo's meshes, and executed, far_left's swinging left hip struck the hanging left
#: hand (22 N) and the robot fell (docs/execution.md, session 60)
HAND_LEG_PAIRS: tuple[tuple[str, str], ...] = tuple(
    (hand, f"{side}_{link}_link") for side, hand in HAND_BODIES.items()
    for link in ("hip_pitch", "hip_roll", "hip_yaw", "knee"))


@dataclass
class GuardRow:
    """One active pair: its bodies, distance (m) and the row on qdd with its lower bound."""

    pair: tuple[str, str]
    distance: float
    row: np.ndarray
    lower: float


class SelfCollisionGuard:
    """Barrier rows for body pairs of one MuJoCo model (collision geoms only)."""

    def __init__(self, model: mujoco.MjModel, pairs=HIP_PAIRS, activation: float = 0.02,
                 rate: float = 10.0, min_distance: float = 0.001) -> None:
        self.model = model
        self.activation, self.rate, self.min_distance = activation, rate, min_distance
        self.pairs: list[tuple[tuple[str, str], int, int, list[tuple[int, int]]]] = []
        for a, b in pairs:
            ia, ib = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in (a, b))
            if ia < 0 or ib < 0:
                raise ValueError(f"self-collision guard: no body {a if ia < 0 else b!r} in the model")
            geoms = [(ga, gb) for ga in self._collision_geoms(ia) for gb in self._collision_geoms(ib)]
            if geoms:
                self.pairs.append(((a, b), ia, ib, geoms))
        self._fromto = np.zeros(6)
        self._ja = np.zeros((3, model.nv))
        self._jb = np.zeros((3, model.nv))

    def guard_object(self, a: str, root: int) -> tuple[str, str]:
        """Add the pair of body ``a`` and every collision geom of the free object rooted at body
        ``root`` (its wheels, handle, ...); returns the pair's key for :meth:`rows`' ``skip``."""
        m = self.model
        ia = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, a)
        if ia < 0:
            raise ValueError(f"self-collision guard: no body {a!r} in the model")
        key = (a, m.body(root).name)
        bodies = [b for b in range(m.nbody) if m.body_rootid[b] == root]
        geoms = [(ga, gb) for ga in self._collision_geoms(ia) for b in bodies for gb in self._collision_geoms(b)]
        if geoms:
            self.pairs.append((key, ia, root, geoms))
        return key

    def _collision_geoms(self, body: int) -> list[int]:
        m = self.model
        return [g for g in range(m.ngeom) if m.geom_bodyid[g] == body and (m.geom_contype[g] or m.geom_conaffinity[g])]

    def closest(self, data: mujoco.MjData, geoms) -> tuple[float, np.ndarray, np.ndarray]:
        """(signed distance, point on a, point on b) of the closest geom pair; distance capped at
        ``activation`` (then the points are meaningless)."""
        best, pa, pb = np.inf, np.zeros(3), np.zeros(3)
        xpos, rbound = data.geom_xpos, self.model.geom_rbound
        for ga, gb in geoms:
            if np.linalg.norm(xpos[ga] - xpos[gb]) - rbound[ga] - rbound[gb] >= self.activation:
                continue   # bounding spheres apart by more than the activation distance
            d = mujoco.mj_geomDistance(self.model, data, ga, gb, self.activation, self._fromto)
            if d < best:
                best, pa, pb = d, self._fromto[:3].copy(), self._fromto[3:].copy()
        return float(best), pa, pb

    def rows(self, data: mujoco.MjData, dofs: slice, skip=frozenset()) -> list[GuardRow]:
        """The rows of the pairs nearer than ``activation`` (columns: the robot's dofs), but
        those whose key is in ``skip``."""
        out = []
        v = data.qvel[dofs]
        for pair, ia, ib, geoms in self.pairs:
            if pair in skip:
                continue
            d, pa, pb = self.closest(data, geoms)
            if d >= self.activation:
                continue
            gap = pb - pa
            norm = float(np.linalg.norm(gap))
            if norm < 1e-9:   # touching at one point: no direction; the bodies' centres apart
                gap, norm = data.xpos[ib] - data.xpos[ia], float(np.linalg.norm(data.xpos[ib] - data.xpos[ia]))
                if norm < 1e-9:
                    continue
            # fromto runs a -> b when apart; when they overlap it runs the other way (b's deepest
            # point lies inside a), so the separating direction flips with the distance's sign
            n = gap / norm if d >= 0 else -gap / norm
            mujoco.mj_jac(self.model, data, self._ja, None, pa, ia)
            mujoco.mj_jac(self.model, data, self._jb, None, pb, ib)
            row = n @ (self._jb[:, dofs] - self._ja[:, dofs])
            d_dot = float(row @ v)
            lower = -2.0 * self.rate * d_dot - self.rate ** 2 * (d - self.min_distance)
            out.append(GuardRow(pair, d, row, lower))
        return out
