"""Measured contact forces per robot limb, read from MuJoCo's contact solver.

Why: the executor logs and plots what physics really applied at the feet and hands next to what
the plan asked for. A limb's force is the sum over active contacts between its geoms (feet: all
geoms of the ankle-roll link; hands: the wrist-yaw link incl. the hand collision box) and anything
that is not the robot, expressed in the world frame as the force ON the robot.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .robot_model import FOOT_BODIES, HAND_BODIES, PELVIS_BODY

LIMB_BODIES = {"left_foot": FOOT_BODIES["left"], "right_foot": FOOT_BODIES["right"],
               "left_hand": HAND_BODIES["left"], "right_hand": HAND_BODIES["right"]}  # fmt: skip


class LimbForceMeter:
    """Sums contact forces on the G1's feet and hands from ``data.contact``."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, PELVIS_BODY)
        self.robot_bodies = {b for b in range(model.nbody) if model.body_rootid[b] == model.body_rootid[pelvis]}
        self.geom_limb: dict[int, str] = {}
        for limb, body in LIMB_BODIES.items():
            bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
            for g in range(model.body_geomadr[bid], model.body_geomadr[bid] + model.body_geomnum[bid]):
                self.geom_limb[g] = limb
        self._f6 = np.zeros(6)
        self._is_limb = np.zeros(model.ngeom, bool)
        self._is_limb[list(self.geom_limb)] = True

    def measure(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        """limb -> world force (3,) applied on the robot by its contacts (zeros when none)."""
        m = self.model
        out = {limb: np.zeros(3) for limb in LIMB_BODIES}
        n = int(data.ncon)
        if n == 0:
            return out
        geoms = data.contact.geom[:n]
        on_limb = self._is_limb[geoms]  # (n, 2): which side of each contact is a foot or hand geom
        frames = data.contact.frame[:n]
        for i in np.flatnonzero(on_limb[:, 0] != on_limb[:, 1]):  # the Python loop sees limb contacts only
            g1, g2 = int(geoms[i, 0]), int(geoms[i, 1])
            l1, l2 = self.geom_limb.get(g1), self.geom_limb.get(g2)
            if (l1 is None) == (l2 is None):
                continue  # not a limb contact, or limb-limb
            other = g2 if l1 is not None else g1
            if m.geom_bodyid[other] in self.robot_bodies:
                continue  # self-contact
            mujoco.mj_contactForce(m, data, int(i), self._f6)
            frame = frames[i].reshape(3, 3)  # rows: normal (from geom[0] to geom[1]), tangents
            f_world = frame.T @ self._f6[:3]  # force on geom[1] from geom[0]... sign fixed below
            # mj_contactForce gives the force that geom[0] exerts on geom[1] along +normal reversed:
            # the contact normal points from geom[0] to geom[1] and the normal force pushes them apart,
            # so geom[1] receives +f_world and geom[0] receives -f_world.
            if l1 is not None:
                out[l1] -= f_world
            else:
                out[l2] += f_world
        return out


def centre_of_pressure(model: mujoco.MjModel, data: mujoco.MjData, body: int,
                       min_force: float = 1.0) -> tuple[np.ndarray, float] | None:
    """(world point (3,), summed normal force N) of the contacts on ``body``, or None below ``min_force``.

    The normal-force-weighted mean of the contact points: the centre of pressure of a sole on a
    plane (the G1's soles touch through four corner spheres). Why: a centre of pressure on the
    sole's edge says the foot is about to roll, which the limb's net force does not show
    (tools/exec_trace.py; docs/execution.md, session 29).
    """
    num, den, f6 = np.zeros(3), 0.0, np.zeros(6)
    for i in range(int(data.ncon)):
        c = data.contact[i]
        if body in (model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]):
            mujoco.mj_contactForce(model, data, i, f6)
            num += f6[0] * c.pos
            den += f6[0]
    if den < min_force:
        return None
    return num / den, float(den)


def centre_of_pressure_in_body(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> np.ndarray | None:
    """(2,) :func:`centre_of_pressure` of ``body``'s contacts in the body's own frame (x, y), or None
    when unloaded: for a sole, where on it the load sits (the G1's foot frame as ``FOOT_CONTACT_POINTS``)."""
    found = centre_of_pressure(model, data, body)
    if found is None:
        return None
    R = data.xmat[body].reshape(3, 3)
    return (R.T @ (found[0] - data.xpos[body]))[:2]


#: an arm's links whose contacts with a held object count as its grip (the hand box is on the wrist-yaw link)
ARM_LINKS = ("elbow_link", "wrist_roll_link", "wrist_pitch_link", "wrist_yaw_link")


def arm_contacts_on(model: mujoco.MjModel, data: mujoco.MjData, side: str,
                    body: int) -> list[tuple[str, np.ndarray, float, float]]:
    """[(link, point in ``body``'s frame (3,), normal force N, tangential force N)] of every contact
    between the ``side`` ("left" / "right") arm's elbow and wrist links and body ``body``.

    Why: where on a held box each hand presses, and how close to sliding (tangential over normal
    against the friction coefficient), says how a grip gives way; the limb's net force does not
    (tools/exec_trace.py --grip; docs/execution.md, session 48).
    """
    links = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{side}_{name}"): name for name in ARM_LINKS}
    links.pop(-1, None)
    R, p = data.xmat[body].reshape(3, 3), data.xpos[body]
    out, f6 = [], np.zeros(6)
    for i in range(int(data.ncon)):
        c = data.contact[i]
        b1, b2 = int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])
        arm = b1 if b2 == body else b2 if b1 == body else None
        if arm is None or arm not in links:
            continue
        mujoco.mj_contactForce(model, data, i, f6)
        out.append((links[arm], R.T @ (c.pos - p), float(f6[0]), float(np.hypot(f6[1], f6[2]))))
    return out


def contact_force_totals(model: mujoco.MjModel, data: mujoco.MjData, key) -> dict:
    """Net contact force (world frame, N) per key over the current contacts: ``key(body1, body2)``
    names what a contact between the two bodies counts for, or None to leave it out. Read after
    mj_step2 (after mj_step1 the contact list is new and the forces are the last step's)."""
    totals: dict = {}
    f6 = np.zeros(6)
    for ci in range(data.ncon):
        c = data.contact[ci]
        k = key(int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2]))
        if k is None:
            continue
        mujoco.mj_contactForce(model, data, ci, f6)
        totals[k] = totals.get(k, np.zeros(3)) + c.frame.reshape(3, 3).T @ f6[:3]
    return totals
