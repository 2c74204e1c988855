"""The perception pipeline: prompts + scene RGB-D + scene objects -> 3D contacts per subtask.

Paper Sec. III-A1 and III-A2, with every learned model behind a role (roles.py) so the offline
'synthetic' backends and, later, the paper's models plug in unchanged. No ROS here: the node
(perception_node.py) converts messages to these types and back (conversions.py).
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from lomanip_sim import frames

from .datatypes import GenerationRequest, PerceptionImage, PinholeCamera
from .errors import CONTACT_TRANSFER_FAILED, INVALID_REQUEST, NO_HUMAN_FOUND, PerceptionError
from .prompts import Subtask, generation_prompt, parse_prompts
from .registry import ModelSet
from .scene import ObjectGeometry
from .synthetic.standins import SceneGroundTruth
from .transfer import ContactTransfer, ObjectTransfer, TransferConfig, lift_keypoints

FLOOR_ID = "floor"
LIMB_KEYPOINT = {"left_hand": "left_hand", "right_hand": "right_hand", "left_foot": "left_foot",
                 "right_foot": "right_foot"}
#: the joint each limb comes from: its contact goes to a surface facing it (a departure from the
#: paper's closest surface; scene.ObjectGeometry.project_to_surface_facing)
LIMB_APPROACH_KEYPOINT = {"left_hand": "left_elbow", "right_hand": "right_elbow", "left_foot": "left_knee",
                          "right_foot": "right_knee"}


@dataclass
class SceneInput:
    """The simulated scene: one RGB-D frame R_s, D_s (true intrinsics and pose) and its objects."""

    image: PerceptionImage
    objects: list[ObjectGeometry]

    def classes(self) -> set[str]:
        return {o.object_class for o in self.objects}

    def first_of_class(self, cls: str) -> ObjectGeometry:
        return next(o for o in self.objects if o.object_class == cls)


@dataclass(frozen=True)
class ContactPoint:
    limb: str
    object_id: str
    position: np.ndarray
    normal: np.ndarray
    confidence: float


@dataclass
class SubtaskResult:
    index: int
    prompt: str
    generation_prompt: str
    contacts: list[ContactPoint]
    keypoints_world: dict[str, np.ndarray]
    joint_names: tuple[str, ...]
    joint_angles: np.ndarray
    pose_confidence: float
    transfers: dict[str, ObjectTransfer]
    timings: dict[str, float]
    demo: PerceptionImage | None = None
    demo_depth: np.ndarray | None = None
    raw_points: dict[str, np.ndarray] = field(default_factory=dict)  # before surface projection
    root_quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))  # pelvis (w,x,y,z), world


def pelvis_orientation(kp: dict[str, np.ndarray]) -> np.ndarray:
    """World pelvis orientation (w, x, y, z) of a transferred pose: z along pelvis -> neck, y along
    right hip -> left hip, x = y cross z (the way the person faces). Identity if keypoints are missing."""
    try:
        up = kp["neck"] - kp["pelvis"]
        left = kp["left_hip"] - kp["right_hip"]
    except KeyError:
        return np.array([1.0, 0.0, 0.0, 0.0])
    z = up / max(np.linalg.norm(up), 1e-9)
    y = left - (left @ z) * z
    if np.linalg.norm(y) < 1e-6:
        return np.array([1.0, 0.0, 0.0, 0.0])
    y /= np.linalg.norm(y)
    return frames.matrix_to_quat(np.column_stack([np.cross(y, z), y, z]))


def validate_scene(scene: SceneInput) -> None:
    img = scene.image
    if img.rgb is None or img.rgb.ndim != 3 or img.rgb.shape[2] != 3 or img.rgb.size == 0:
        raise PerceptionError(INVALID_REQUEST, "scene RGB image is empty or not HxWx3")
    if img.depth is None or img.depth.shape != img.rgb.shape[:2]:
        raise PerceptionError(INVALID_REQUEST, f"scene depth image is missing or its shape "
                              f"{None if img.depth is None else img.depth.shape} differs from the RGB {img.rgb.shape[:2]}")
    finite = np.isfinite(img.depth) & (img.depth > 0)
    if not finite.any():
        raise PerceptionError(INVALID_REQUEST, "scene depth image has no finite positive values (all NaN/inf/0)")
    if img.camera is None or not (img.camera.fx > 0 and img.camera.fy > 0):
        raise PerceptionError(INVALID_REQUEST, "scene camera intrinsics are missing or invalid (fx, fy must be > 0)")
    if img.camera_pose is None:
        raise PerceptionError(INVALID_REQUEST, "scene camera pose is missing")
    if not scene.objects:
        raise PerceptionError(INVALID_REQUEST, "no scene objects known (is /lomanip/scene_objects published?)")


class PerceptionPipeline:
    def __init__(self, models: ModelSet, transfer: TransferConfig | None = None, seed: int = 0,
                 generation_size: tuple[int, int] = (1024, 1024), logger: logging.Logger | None = None):  # fmt: skip
        self.models = models
        self.transfer = ContactTransfer(transfer)
        self.seed = int(seed)
        self.generation_size = generation_size
        self.log = logger or logging.getLogger("lomanip_perception")

    @property
    def method(self) -> str:
        return self.transfer.config.method

    def parse(self, prompts: list[str], scene: SceneInput) -> list[Subtask]:
        return parse_prompts([p for p in prompts], scene.classes())

    def run(self, prompts: list[str], scene: SceneInput, keep_images: bool = False) -> list[SubtaskResult]:
        subtasks = self.parse(list(prompts), scene)  # all prompts checked before any heavy work
        validate_scene(scene)
        return [self.run_subtask(st, scene, keep_images) for st in subtasks]

    @staticmethod
    def _project(obj, pose, limbs, pts: np.ndarray, tr, gen_depth: np.ndarray, gen_cam: PinholeCamera):
        """Transferred limb points onto ``obj``'s surface: each onto a face that looks towards the
        limb's elbow or knee (transferred the same way), else onto the closest surface."""
        names = [LIMB_APPROACH_KEYPOINT.get(limb) for limb in limbs]
        if not all(n in pose.keypoint_names for n in names):
            return obj.project_to_surface(pts)
        toward = tr.apply(lift_keypoints(pose, names, gen_depth, gen_cam))
        return obj.project_to_surface_facing(pts, toward)

    def _mask(self, image: PerceptionImage, cls: str, where: str, label: str, cache: dict) -> np.ndarray:
        key = (where, cls)
        if key in cache:
            return cache[key]
        dets = self.models.detector.detect(image, [cls])
        if not dets:
            raise PerceptionError(CONTACT_TRANSFER_FAILED, f"{label}: the detector found no {cls!r} in the {where}")
        mask = self.models.segmenter.segment(image, dets[:1])[0]
        if mask is None or not mask.any():
            raise PerceptionError(CONTACT_TRANSFER_FAILED, f"{label}: empty mask for {cls!r} in the {where}")
        cache[key] = mask
        return mask

    def generate(self, st: Subtask, scene: SceneInput, seed: int | None = None) -> PerceptionImage:
        """The demonstration image R_g of one subtask (the paper's prompt template)."""
        ref = {}
        for o in scene.objects:
            ref.setdefault(o.object_class, tuple(2.0 * o.bbox_local()[1]))
        W, H = self.generation_size
        seed = self.seed * 1000 + st.index if seed is None else seed
        return self.models.image_generator.generate(GenerationRequest(generation_prompt(st.prompt), seed, st, W, H, ref))

    def run_subtask(self, st: Subtask, scene: SceneInput, keep_images: bool = False,
                    demo: PerceptionImage | None = None) -> SubtaskResult:  # fmt: skip
        """Contacts of one subtask; ``demo`` reuses an already generated R_g (benchmarks)."""
        timings: dict[str, float] = {}
        label = st.label
        if scene.image.ground_truth is None:
            # what the synthetic stand-ins may read about a simulated scene: its objects' geometry
            # (real model adapters ignore it)
            scene.image.ground_truth = SceneGroundTruth(list(scene.objects))
        t = time.perf_counter()
        text = generation_prompt(st.prompt)
        gen = demo if demo is not None else self.generate(st, scene)
        timings["image_generation"] = time.perf_counter() - t
        t = time.perf_counter()
        pose = self.models.pose_estimator.estimate(gen)
        timings["pose_estimation"] = time.perf_counter() - t
        if pose is None:
            raise PerceptionError(NO_HUMAN_FOUND, f"{label}: no person found in the generated image", st.index)
        t = time.perf_counter()
        gen_depth = self.models.depth_estimator.estimate(gen)
        timings["depth_estimation"] = time.perf_counter() - t
        gen_cam = PinholeCamera.paper_heuristic(gen.width, gen.height)
        masks: dict = {}
        transfers: dict[str, ObjectTransfer] = {}
        contacts: list[ContactPoint] = []
        raw: dict[str, np.ndarray] = {}
        t_seg = t_tr = 0.0
        for inter in st.interactions:
            obj = scene.first_of_class(inter.object_class)
            t = time.perf_counter()
            try:
                mg = self._mask(gen, inter.object_class, "generated image", label, masks)
                ms = self._mask(scene.image, inter.object_class, "scene image", label, masks)
            except PerceptionError as e:
                e.subtask_index = st.index
                raise
            t_seg += time.perf_counter() - t
            t = time.perf_counter()
            if obj.id not in transfers:
                transfers[obj.id] = self.transfer.estimate(gen, gen_depth, gen_cam, mg, scene.image, ms, obj,
                                                           self.models.matcher, label)  # fmt: skip
            tr = transfers[obj.id]
            names = [LIMB_KEYPOINT[limb] for limb in inter.limbs]
            if self.method == "geometry_unaware":
                idx = [pose.index(n) for n in names]
                pts = self.transfer.unaware_points(gen, mg, pose.uv[idx], scene.image, ms, self.models.matcher, label)
                proj, normals = obj.project_to_surface(pts)
            else:
                pts = tr.apply(lift_keypoints(pose, names, gen_depth, gen_cam))
                proj, normals = self._project(obj, pose, inter.limbs, pts, tr, gen_depth, gen_cam)
            for limb, p_raw, p, n in zip(inter.limbs, pts, proj, normals):
                raw[limb] = p_raw
                conf = float(np.clip(tr.overlap if self.method == "geometry_aware" else 0.5, 0, 1) * pose.confidence)
                contacts.append(ContactPoint(limb, obj.id, p, n, conf))
            t_tr += time.perf_counter() - t
        timings["detection_segmentation"] = t_seg
        timings["contact_transfer"] = t_tr
        primary = transfers[scene.first_of_class(st.interactions[0].object_class).id]
        kp_cam = lift_keypoints(pose, list(pose.keypoint_names), gen_depth, gen_cam)
        kp_world = dict(zip(pose.keypoint_names, primary.apply(kp_cam)))
        touched = {c.limb for c in contacts}
        for limb in ("left_foot", "right_foot"):
            if limb not in touched:  # standing on the floor: where the person stands relative to the object
                p = kp_world[limb].copy()
                p[2] = 0.0
                contacts.append(ContactPoint(limb, FLOOR_ID, p, np.array([0.0, 0.0, 1.0]),
                                             0.5 * float(np.clip(primary.overlap, 0, 1)) * pose.confidence))
        self.log.info(f"{label}: {len(contacts)} contacts ({self.method}, synthetic models: "
                      f"{', '.join(r for r, n in self.models.names().items() if n == 'synthetic')}); "
                      f"transfer {t_tr:.2f} s")  # fmt: skip
        return SubtaskResult(st.index, st.prompt, text, contacts, kp_world, tuple(pose.joint_names),
                             np.asarray(pose.joint_angles), float(pose.confidence), transfers, timings,
                             gen if keep_images else None, gen_depth if keep_images else None, raw,
                             pelvis_orientation(kp_world))  # fmt: skip
