"""An articulated human body of adult proportions, posed by inverse kinematics (synthetic only).

Why: a synthetic demonstration must show a person whose hands and feet touch the object where a
person doing the subtask would. The body is a skeleton of 23 keypoints with anthropometric segment
lengths (fractions of stature, e.g. thigh 0.245 H, upper arm 0.186 H); it is posed by choosing the
pelvis position, height, yaw and forward lean with a small grid search, and each limb by analytic
two-bone IK (elbows out and back, knees forward) onto the palm/sole targets; candidate poses whose
torso, head, thighs, shins or upper arms penetrate an object are rejected. The posed skeleton is
drawn as capsules (shirt, jeans, sneakers, skin, dark hair).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..scene import ObjectGeometry

KEYPOINTS = ("pelvis", "spine", "neck", "head",
             "left_shoulder", "left_elbow", "left_wrist", "left_hand",
             "right_shoulder", "right_elbow", "right_wrist", "right_hand",
             "left_hip", "left_knee", "left_ankle", "left_heel", "left_toe", "left_foot",
             "right_hip", "right_knee", "right_ankle", "right_heel", "right_toe", "right_foot")  # fmt: skip
#: keypoint at which each limb touches: palm centre for hands, sole centre for feet
CONTACT_KEYPOINT = {"left_hand": "left_hand", "right_hand": "right_hand", "left_foot": "left_foot",
                    "right_foot": "right_foot"}


@dataclass(frozen=True)
class BodyDims:
    """Segment lengths of a person of stature ``height`` (metres)."""

    height: float = 1.75

    def __getattr__(self, name):  # scaled anthropometric lengths
        table = {"thigh": 0.245, "shin": 0.246, "ankle_h": 0.04, "spine": 0.32, "shoulder_drop": 0.034,
                 "shoulder_w": 0.11, "hip_w": 0.052, "upper_arm": 0.186, "forearm": 0.146, "palm": 0.043,
                 "hand_len": 0.095, "neck": 0.046, "head_r": 0.056, "foot_back": 0.046, "foot_fwd": 0.08,
                 "stance_w": 0.066, "palm_off": 0.012}
        if name in table:
            return table[name] * self.height
        raise AttributeError(name)

    @property
    def hip_height(self) -> float:
        return self.thigh + self.shin + self.ankle_h

    @property
    def arm(self) -> float:
        return self.upper_arm + self.forearm


def two_bone(root: np.ndarray, target: np.ndarray, l1: float, l2: float, pole: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Middle joint and reached end point of a two-bone chain aiming at ``target``."""
    d_vec = target - root
    d = float(np.linalg.norm(d_vec))
    u = d_vec / max(d, 1e-9)
    dc = float(np.clip(d, abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4))
    cos_a = (l1 * l1 + dc * dc - l2 * l2) / (2 * l1 * dc)
    v = pole - (pole @ u) * u
    nv = np.linalg.norm(v)
    if nv < 1e-9:
        v = np.cross(u, [0.0, 0.0, 1.0])
        nv = np.linalg.norm(v) if np.linalg.norm(v) > 1e-9 else 1.0
    v = v / nv
    mid = root + l1 * (cos_a * u + np.sqrt(max(0.0, 1 - cos_a * cos_a)) * v)
    return mid, root + dc * u


@dataclass
class Skeleton:
    points: dict[str, np.ndarray]
    hand_dirs: dict[str, np.ndarray] = field(default_factory=dict)
    foot_dirs: dict[str, np.ndarray] = field(default_factory=dict)
    yaw: float = 0.0
    lean: float = 0.0

    def array(self) -> np.ndarray:
        return np.stack([self.points[k] for k in KEYPOINTS])


@dataclass(frozen=True)
class HandTarget:
    contact: np.ndarray  # on the object surface
    normal: np.ndarray  # outward surface normal (towards the palm)


def _frame(yaw: float):
    f = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    left = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    return f, left, np.array([0.0, 0.0, 1.0])


def _hand_dir(palm: np.ndarray, shoulder: np.ndarray, normal: np.ndarray) -> np.ndarray:
    v = palm - shoulder
    v = v - (v @ normal) * normal
    if np.linalg.norm(v) < 1e-6:
        v = np.array([0.0, 0.0, -1.0]) - normal[2] * normal
    return v / np.linalg.norm(v)


def pose_skeleton(dims: BodyDims, pelvis: np.ndarray, yaw: float, lean: float,
                  hands: dict[str, HandTarget], soles: dict[str, np.ndarray]) -> Skeleton:  # fmt: skip
    """Pose every keypoint for a root pose and limb targets (IK). ``soles`` must hold both feet."""
    f, left, z = _frame(yaw)
    P = {}
    spine_dir = np.cos(lean) * z + np.sin(lean) * f
    P["pelvis"] = pelvis
    P["spine"] = pelvis + 0.5 * dims.spine * spine_dir
    neck = pelvis + (dims.spine + dims.shoulder_drop) * spine_dir
    P["neck"] = neck
    head_dir = spine_dir + 0.8 * np.sin(lean) * z
    head_dir /= np.linalg.norm(head_dir)
    P["head"] = neck + (dims.neck + dims.head_r) * head_dir
    hand_dirs, foot_dirs = {}, {}
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        sh = neck - dims.shoulder_drop * spine_dir + sgn * dims.shoulder_w * left
        P[f"{side}_shoulder"] = sh
        tgt = hands.get(f"{side}_hand")
        if tgt is not None:
            palm = tgt.contact + dims.palm_off * tgt.normal
            hd = _hand_dir(palm, sh, tgt.normal)
            wrist_t = palm - dims.palm * hd
        else:  # relaxed arm, slightly forward and out
            hd = -z
            wrist_t = sh + dims.arm * 0.95 * np.array(-z * 0.97 + 0.15 * sgn * left + 0.1 * f)
            palm = wrist_t + dims.palm * hd
        pole = -0.4 * z + 0.8 * sgn * left - 0.5 * f
        elbow, wrist = two_bone(sh, wrist_t, dims.upper_arm, dims.forearm, pole)
        P[f"{side}_elbow"], P[f"{side}_wrist"], P[f"{side}_hand"] = elbow, wrist, wrist + dims.palm * hd
        hand_dirs[side] = hd
        hip = pelvis + sgn * dims.hip_w * left
        P[f"{side}_hip"] = hip
        sole = soles[f"{side}_foot"]
        g = f  # feet point where the body faces
        ankle_t = sole + dims.ankle_h * z - 0.35 * dims.foot_back * g
        knee, ankle = two_bone(hip, ankle_t, dims.thigh, dims.shin, f + 0.25 * sgn * left)
        P[f"{side}_knee"], P[f"{side}_ankle"] = knee, ankle
        P[f"{side}_heel"] = sole - dims.foot_back * g
        P[f"{side}_toe"] = sole + dims.foot_fwd * g
        P[f"{side}_foot"] = sole
        foot_dirs[side] = g
    return Skeleton(P, hand_dirs, foot_dirs, yaw, lean)


def reach_errors(dims: BodyDims, sk: Skeleton, hands: dict[str, HandTarget], soles: dict[str, np.ndarray]) -> float:
    """Largest distance (m) by which a limb falls short of its target."""
    err = 0.0
    for limb, tgt in hands.items():
        palm = tgt.contact + dims.palm_off * tgt.normal
        err = max(err, float(np.linalg.norm(sk.points[limb] - palm)))
    for limb, sole in soles.items():
        side = limb.split("_")[0]
        ankle_t = sole + dims.ankle_h * np.array([0, 0, 1.0]) - 0.35 * dims.foot_back * sk.foot_dirs[side]
        err = max(err, float(np.linalg.norm(sk.points[f"{side}_ankle"] - ankle_t)))
    return err


#: body segments checked against objects: (from, to, radius as a fraction of stature)
_COLLISION_SEGMENTS = [("pelvis", "neck", 0.060), ("neck", "head", 0.045), ("left_hip", "left_knee", 0.036),
                       ("right_hip", "right_knee", 0.036), ("left_knee", "left_ankle", 0.027),
                       ("right_knee", "right_ankle", 0.027), ("left_shoulder", "left_elbow", 0.024),
                       ("right_shoulder", "right_elbow", 0.024)]


def penetration(dims: BodyDims, sk: Skeleton, objects: list[ObjectGeometry]) -> float:
    """Deepest penetration (m, >= 0) of the checked body segments into any object."""
    pts, radii = [], []
    for a, b, r in _COLLISION_SEGMENTS:
        for s in np.linspace(0.0, 1.0, 6):
            pts.append((1 - s) * sk.points[a] + s * sk.points[b])
            radii.append(r * dims.height)
    pts, radii = np.array(pts), np.array(radii)
    worst = 0.0
    for obj in objects:
        sd, _, _ = obj.signed_distance(pts)
        worst = max(worst, float(np.max(radii - sd)))
    return max(worst, 0.0)


def solve_pose(dims: BodyDims, approach_yaw: float, hands: dict[str, HandTarget],
               soles_fixed: dict[str, np.ndarray] | None, objects: list[ObjectGeometry],
               ground_z: float = 0.0, rng: np.random.Generator | None = None) -> tuple[Skeleton, float]:  # fmt: skip
    """Find pelvis position/height and lean so the hands reach their targets with the feet on the
    floor (or on ``soles_fixed``) and the body clear of objects. Returns (skeleton, reach error)."""
    rng = rng or np.random.default_rng(0)
    f, left, z = _frame(approach_yaw)
    H0 = dims.hip_height
    if hands:
        centre = np.mean([t.contact for t in hands.values()], axis=0)
    else:
        centre = np.mean(list(soles_fixed.values()), axis=0)
    base_z = ground_z
    if soles_fixed:
        feet_mid = np.mean(list(soles_fixed.values()), axis=0)
        base_z = float(feet_mid[2])
        ds = np.linspace(-0.08, 0.12, 6) * dims.height / 1.75
        ks = np.array([0.0])
        hs = base_z + H0 * np.linspace(0.80, 0.985, 6)
        leans = np.deg2rad(np.linspace(0, 40, 9))
    else:
        ds = np.linspace(0.05, 0.85, 17)
        ks = np.array([0.0, 0.1, 0.2, 0.3])
        hs = ground_z + H0 * np.linspace(0.50, 0.985, 10)
        leans = np.deg2rad(np.linspace(0, 80, 11))
    D, Hh, Ln, Kk = (a.ravel() for a in np.meshgrid(ds, hs, leans, ks, indexing="ij"))
    if soles_fixed:
        pxy = feet_mid[None, :] - D[:, None] * f
    else:
        pxy = centre[None, :] - D[:, None] * f
    pelvis = np.column_stack([pxy[:, 0], pxy[:, 1], Hh])
    spine_dir = np.cos(Ln)[:, None] * z + np.sin(Ln)[:, None] * f
    neck = pelvis + (dims.spine + dims.shoulder_drop) * spine_dir
    bad = np.zeros(len(D))
    cost = 2.0 * ((base_z + H0 - Hh) / H0) ** 2 + 1.2 * Ln ** 2 + 0.6 * Kk ** 2 + 0.02 * rng.random(len(D))
    soles_all = {}
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        sh = neck - dims.shoulder_drop * spine_dir + sgn * dims.shoulder_w * left
        t = hands.get(f"{side}_hand")
        if t is not None:
            r = np.linalg.norm(t.contact + dims.palm_off * t.normal - sh, axis=1) / (dims.arm + dims.palm)
            bad += np.maximum(0.0, r - 0.97) + np.maximum(0.0, 0.35 - r)
            cost += 0.5 * (r - 0.8) ** 2
        hip = pelvis + sgn * dims.hip_w * left
        if soles_fixed:
            sole = np.broadcast_to(soles_fixed[f"{side}_foot"], pelvis.shape)
        else:
            sxy = pxy + Kk[:, None] * f + sgn * dims.stance_w * left
            sole = np.column_stack([sxy[:, 0], sxy[:, 1], np.full(len(D), ground_z)])
        soles_all[f"{side}_foot"] = sole
        rl = np.linalg.norm(sole + dims.ankle_h * z - hip, axis=1) / (dims.thigh + dims.shin)
        bad += np.maximum(0.0, rl - 0.995) + np.maximum(0.0, 0.5 - rl)
    ok = np.nonzero(bad <= 0)[0]
    order = ok[np.argsort(cost[ok])]
    cands = [(cost[i], pelvis[i], Ln[i], {k: v[i].copy() for k, v in soles_all.items()}) for i in order[:400]]
    cands.sort(key=lambda c: c[0])
    best, best_key = None, None
    for cost, pelvis, lean, soles in cands[:400]:
        sk = pose_skeleton(dims, pelvis, approach_yaw, lean, hands, soles)
        pen = penetration(dims, sk, objects)
        err = reach_errors(dims, sk, hands, soles)
        key = (pen > 0.01, pen + err, cost)
        if best_key is None or key < best_key:
            best, best_key = (sk, err), key
        if pen <= 0.01 and err < 0.01:
            return sk, err
    if best is None:  # nothing reachable: stand as close as possible (caller checks the error)
        pelvis = np.array([*(centre - 0.4 * f)[:2], ground_z + H0 * 0.95])
        soles = soles_fixed or {"left_foot": np.array([*(pelvis + dims.stance_w * left)[:2], ground_z]),
                                "right_foot": np.array([*(pelvis - dims.stance_w * left)[:2], ground_z])}
        sk = pose_skeleton(dims, pelvis, approach_yaw, 0.0, hands, soles)
        return sk, reach_errors(dims, sk, hands, soles)
    return best


@dataclass(frozen=True)
class Appearance:
    skin: tuple
    hair: tuple
    shirt: tuple
    jeans: tuple
    shoes: tuple


def random_appearance(rng: np.random.Generator) -> Appearance:
    skins = [(0.96, 0.80, 0.69), (0.87, 0.67, 0.52), (0.72, 0.52, 0.38), (0.55, 0.38, 0.26), (0.40, 0.27, 0.18)]
    shirts = [(0.80, 0.15, 0.15), (0.15, 0.55, 0.25), (0.95, 0.95, 0.92), (0.2, 0.2, 0.22), (0.9, 0.6, 0.1),
              (0.45, 0.3, 0.6), (0.3, 0.6, 0.85)]  # fmt: skip
    jeans = (0.12 + 0.06 * rng.random(), 0.18 + 0.06 * rng.random(), 0.38 + 0.12 * rng.random())
    shoes = [(0.95, 0.95, 0.95), (0.15, 0.15, 0.15), (0.85, 0.2, 0.2)]
    return Appearance(skin=(*skins[rng.integers(len(skins))], 1.0), hair=(0.07, 0.05, 0.04, 1.0),
                      shirt=(*shirts[rng.integers(len(shirts))], 1.0), jeans=(*jeans, 1.0),
                      shoes=(*shoes[rng.integers(len(shoes))], 1.0))


def body_capsules(dims: BodyDims, sk: Skeleton, look: Appearance) -> list[tuple[str, np.ndarray, np.ndarray, float, tuple]]:
    """(name, from, to, radius, rgba) capsules (from == to: sphere) drawing the posed body."""
    P, H = sk.points, dims.height
    out = []
    spine_dir = P["neck"] - P["pelvis"]
    spine_dir /= np.linalg.norm(spine_dir)
    out.append(("hips", P["left_hip"], P["right_hip"], 0.058 * H, look.jeans))
    out.append(("belly", P["pelvis"] + 0.02 * H * spine_dir, P["spine"], 0.066 * H, look.shirt))
    out.append(("chest", P["spine"], P["neck"] - 0.05 * H * spine_dir, 0.074 * H, look.shirt))
    out.append(("shoulders", P["left_shoulder"], P["right_shoulder"], 0.036 * H, look.shirt))
    out.append(("neck", P["neck"] - 0.02 * H * spine_dir, P["head"], 0.024 * H, look.skin))
    out.append(("head", P["head"], P["head"], dims.head_r, look.skin))
    f = np.array([np.cos(sk.yaw), np.sin(sk.yaw), 0.0])
    hair_c = P["head"] - 0.012 * H * f + 0.008 * H * np.array([0, 0, 1.0])
    out.append(("hair", hair_c, hair_c, dims.head_r * 1.02, look.hair))
    for side in ("left", "right"):
        out.append((f"{side}_upper_arm", P[f"{side}_shoulder"], P[f"{side}_elbow"], 0.027 * H, look.shirt))
        out.append((f"{side}_forearm", P[f"{side}_elbow"], P[f"{side}_wrist"], 0.021 * H, look.skin))
        hand_end = P[f"{side}_wrist"] + dims.hand_len * sk.hand_dirs[side]
        out.append((f"{side}_palm", P[f"{side}_wrist"], hand_end, 0.015 * H, look.skin))
        out.append((f"{side}_thigh", P[f"{side}_hip"], P[f"{side}_knee"], 0.040 * H, look.jeans))
        out.append((f"{side}_shin", P[f"{side}_knee"], P[f"{side}_ankle"], 0.030 * H, look.jeans))
        r_foot = 0.026 * H
        up = np.array([0, 0, r_foot])
        out.append((f"{side}_shoe", P[f"{side}_heel"] + up, P[f"{side}_toe"] + up, r_foot, look.shoes))
    return out
