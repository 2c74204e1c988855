"""The plan's own configurations checked against the simulator's collision meshes.

Why: the TO keeps collision spheres apart at its knots; MuJoCo collides the robot's meshes at every
step, and the plan is interpolated between knots. S2's nominal plan (session 49) kept its torso and
hip spheres at 0.0 cm from the table at the knots while the hip meshes cut 3.9 cm into a table leg
between two knots 0.2 s apart; executed, the hip struck the table and the robot fell. This check
poses the robot and the objects as the plan has them (kinematics only, nothing simulated) and lets
MuJoCo's own collision detection, with its own pair filtering, say where meshes overlap.

Contacts the plan intends are not counted: a foot on the floor, and a limb on the object its phase
has it touching (for a hand, its whole forearm: the elbow and wrist links hold a box too).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .contact_forces import ARM_LINKS
from .robot_model import FOOT_BODIES, HAND_BODIES, PELVIS_BODY
from .simulator import Simulation
from .trajectory import FLOOR, Trajectory


@dataclass(frozen=True)
class Penetration:
    """The deepest overlap of one robot body with one other body over the plan."""

    depth: float  # m, > 0: the meshes overlap by this much
    t: float  # s, plan time of the deepest sample
    robot_body: str
    other: str  # a robot body (self), a scene object id, or "floor"
    #: "self"; "arm" (a hand's or forearm's link on an object or the floor: where the plan's hand
    #: point leaves the hand's mesh to the controller's approach); "body" (any other link)
    kind: str

    def __str__(self) -> str:
        return f"{self.robot_body} {self.depth * 100:.1f} cm into {self.other} at t={self.t:.2f} s"


def _limb_links(m: mujoco.MjModel) -> dict[str, set[int]]:
    """Limb name -> robot body ids that may touch what the limb's phase contact touches."""
    out = {}
    for side in ("left", "right"):
        out[f"{side}_foot"] = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, FOOT_BODIES[side])}
        arm = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{side}_{link}") for link in ARM_LINKS}
        out[f"{side}_hand"] = (arm | {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, HAND_BODIES[side])}) - {-1}
    return out


def plan_penetrations(sim: Simulation, traj: Trajectory, every: float = 0.01, min_depth: float = 0.0,
                      start: float = 0.0, stop: float = np.inf) -> list[Penetration]:
    """Deepest mesh overlap per (robot body, other body) over the plan from ``start`` to ``stop`` (s)
    sampled every ``every`` s, deepest first; only overlaps deeper than ``min_depth`` (m).  ``sim``'s
    own state is untouched."""
    m = sim.model
    d = mujoco.MjData(m)
    d.qpos[:] = sim.data.qpos
    pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PELVIS_BODY)
    root = m.body_rootid
    robot = root == root[pelvis]
    feet = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in FOOT_BODIES.values()}
    limbs = _limb_links(m)
    obj_of_root = {}  # root body id -> object id
    obj_qadr = {}  # object id -> qpos address of its free joint (movable objects)
    for oid, info in sim.world.objects.items():
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, info.body_name)
        obj_of_root[int(root[b])] = oid
        if info.movable and m.body_jntnum[b] > 0 and m.jnt_type[m.body_jntadr[b]] == mujoco.mjtJoint.mjJNT_FREE:
            obj_qadr[oid] = int(m.jnt_qposadr[m.body_jntadr[b]])
    bq = int(m.jnt_qposadr[m.body_jntadr[pelvis]])

    def other_name(b: int) -> str:
        if b == 0:
            return FLOOR
        if robot[b]:
            return m.body(b).name
        return obj_of_root.get(int(root[b]), m.body(int(root[b])).name)

    worst: dict[tuple[str, str], Penetration] = {}
    t_next = -np.inf
    for i in range(traj.n):
        t = float(traj.t[i])
        if t < start or t > stop or (t < t_next and i != traj.n - 1):
            continue
        t_next = t + every
        q = traj.qpos(i)
        d.qpos[bq : bq + q.size] = q
        for oid, (pos, quat) in traj.objects.items():
            if oid in obj_qadr:
                d.qpos[obj_qadr[oid] : obj_qadr[oid] + 3] = pos[i]
                d.qpos[obj_qadr[oid] + 3 : obj_qadr[oid] + 7] = quat[i]
        mujoco.mj_fwdPosition(m, d)
        ph = traj.phase_at(t)
        touching = {limb: c.object_id for limb, c in (ph.contacts.items() if ph else ()) if c is not None}
        for c in d.contact[: d.ncon]:
            depth = -float(c.dist)
            if depth <= min_depth:
                continue
            b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
            if not robot[b1]:
                b1, b2 = b2, b1
            if not robot[b1]:
                continue  # object on object, object on floor: not the robot's
            if robot[b2]:
                kind, other = "self", m.body(b2).name
            else:
                kind, other = ("arm" if any(b1 in limbs[f"{s}_hand"] for s in ("left", "right")) else "body"), other_name(b2)
                if b1 in feet and other == FLOOR:
                    continue
                if any(b1 in limbs[limb] and other == oid for limb, oid in touching.items()):
                    continue
            key = (m.body(b1).name, other)
            if key not in worst or depth > worst[key].depth:
                worst[key] = Penetration(depth, t, m.body(b1).name, other, kind)
    return sorted(worst.values(), key=lambda p: -p.depth)
