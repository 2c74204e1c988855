"""The 'synthetic' image generator: a demonstration image R_g of a person doing a subtask.

For a parsed subtask it composes a small scene: the objects the prompt names, each a NEW instance of
its class (full size within +-20 % of the scene's instance when one is given, other colour, other
yaw), placed as the prompt implies (on the floor, on the table/trolley/shelf it names, next to the
shelf, or a basket on a shelf with the box to step on in front of it); it puts an adult-proportion
person's hands and feet where a person doing that action would (side faces to pick up / place,
the face or handle to push, side walls of a basket to grab, the top to step on), solves the body
pose by IK, and renders the scene with MuJoCo from a random viewpoint with a random vertical field
of view (a camera the pipeline is never told), at 1024 x 1024 by default.

The image goes out as a PerceptionImage WITHOUT depth or intrinsics (like an LDM output); its
``ground_truth`` (DemoGroundTruth: true camera, depth, per-pixel labels, object geometry, human
keypoints, true contact points) is read only by the synthetic stand-ins and by evaluation.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field

import lomanip_sim  # noqa: F401  (headless GL backend before mujoco)
import mujoco
import numpy as np
from lomanip_sim import frames

from ..datatypes import GenerationRequest, PerceptionImage, PinholeCamera, RigidPose
from ..errors import INVALID_REQUEST, PerceptionError
from ..prompts import Interaction, Subtask
from ..registry import register
from ..scene import ObjectGeometry
from . import objects as objs
from .human import KEYPOINTS, BodyDims, HandTarget, body_capsules, random_appearance, solve_pose

BACKGROUND, FLOOR, PERSON = -1, 0, 1


@dataclass(frozen=True)
class GTContact:
    limb: str
    object_name: str
    point: np.ndarray  # world, on the object surface
    normal: np.ndarray  # outward
    canonical: np.ndarray  # canonical coordinates on the demo object


@dataclass
class DemoGroundTruth:
    """Everything the synthetic generator knows about the image it drew."""

    subtask: Subtask | None
    objects: dict[str, ObjectGeometry]  # demo objects by name (name == class, unique per demo)
    camera: PinholeCamera  # the TRUE intrinsics (unknown to the pipeline)
    camera_pose: RigidPose  # optical frame in the demo world
    fovy_deg: float
    depth: np.ndarray  # (H, W) metres, +inf background
    labels: np.ndarray  # (H, W) int16: -1 background, 0 floor, 1 person, 2 + k object k
    label_names: list[str]
    keypoints_world: dict[str, np.ndarray]
    keypoints_visible: dict[str, bool]
    contacts: list[GTContact]
    human_present: bool
    reach_error: float = 0.0
    seed: int = 0

    def object_label(self, name: str) -> int:
        return 2 + self.label_names.index(name)

    def mask(self, name: str) -> np.ndarray:
        if name == "person":
            return self.labels == PERSON
        return self.labels == self.object_label(name)

    def names_of_class(self, object_class: str) -> list[str]:
        return [n for n, o in self.objects.items() if o.object_class == object_class]

    def world_points(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        z = self.depth[v, u]
        return self.camera_pose.apply(self.camera.backproject(u, v, z))


# ------------------------------------------------------------------------------------------------
# composition


def _instance_size(cls: str, reference: dict, rng: np.random.Generator, size_range: float) -> np.ndarray:
    base = np.asarray(reference.get(cls, objs.NOMINAL_SIZES[cls]), float)
    s = rng.uniform(1 - size_range, 1 + size_range)
    jitter = rng.uniform(-0.05, 0.05, 3)
    return base * np.clip(s + jitter, 1 - size_range, 1 + size_range)


def _local_to_world(obj: ObjectGeometry, p_local, n_local=None):
    p = obj.to_world(np.asarray(p_local, float))[0]
    if n_local is None:
        return p
    return p, obj.R @ np.asarray(n_local, float)


def _hand_contacts(action: str, obj: ObjectGeometry, approach_local: np.ndarray, rng) -> dict[str, HandTarget]:
    """Palm contact points on ``obj`` for a person facing ``approach_local`` (object frame, unit, horizontal)."""
    c, h = obj.bbox_local()
    a = approach_local / np.linalg.norm(approach_local)  # direction the person faces, in the object frame
    left = np.array([-a[1], a[0], 0.0])
    ext_a = abs(a @ h)  # half extent along the approach
    ext_l = abs(left @ h)
    out = {}
    cls = obj.object_class
    for limb, sgn in (("left_hand", 1.0), ("right_hand", -1.0)):
        if cls == "trolley":
            bar = obj.primitives[3]
            y = sgn * rng.uniform(0.45, 0.7) * bar.size[1]
            n = np.array([-1.0, 0.0, 1.0]) / np.sqrt(2.0)
            p = bar.pos + np.array([0.0, y, 0.0]) + bar.size[0] * n
        elif action == "push" and cls == "table":
            top = obj.primitives[0]
            n = np.array([0.0, 0.0, 1.0])
            p = c + (-ext_a + 0.07) * a + sgn * rng.uniform(0.2, 0.4) * ext_l * left
            p[2] = top.pos[2] + top.size[2]
        elif action == "push" and cls == "shelf":
            leg = max(obj.primitives[1:5], key=lambda q: (q.pos @ (-a)) * 10 + sgn * (q.pos @ left))
            n = -a
            p = leg.pos + abs(a @ np.asarray(leg.size)) * n
            p[2] = min(rng.uniform(0.95, 1.15), c[2] + h[2] - 0.1)
        elif action == "push":  # box, basket: the face the person faces
            n = -a
            p = c - ext_a * a + sgn * rng.uniform(0.3, 0.55) * ext_l * left
            p[2] = c[2] + rng.uniform(0.35, 0.75) * h[2]
        elif cls == "basket":  # grab: outer face of the side walls, near the rim, in their near half
            # (a person lifting a basket off a shelf in front of them holds it towards themselves;
            # held mid-wall, as before session 52, the G1's upper arm lay along the basket and S1's
            # grab from prompts ended 11.6 mm into it; the hand-written fixture holds it 6 cm from
            # the near edge: docs/planner_s1.md, session 52)
            n = sgn * left
            p = c + ext_l * n + rng.uniform(-0.75, -0.45) * ext_a * a
            p[2] = c[2] + h[2] - rng.uniform(0.04, 0.08)
        else:  # pick / place / grab a box-like object: the two side faces, in their upper half
            # (people lift a box by its sides near the top edge; low on the faces the G1 had to
            # squat with its pelvis 16 cm above the floor to reach S1's 30 cm box)
            n = sgn * left
            p = c + ext_l * n + rng.uniform(-0.25, 0.15) * ext_a * a
            p[2] = c[2] + rng.uniform(0.4, 0.75) * h[2]
        pw, _ = _local_to_world(obj, p, n)
        # snap onto the surface (the approach may be a few degrees off the object's axes)
        pw, nw = obj.project_to_surface(pw)
        out[limb] = HandTarget(pw[0], nw[0] / np.linalg.norm(nw[0]))
    return out


def _sole_contacts(obj: ObjectGeometry, approach_local: np.ndarray, dims: BodyDims, rng) -> dict[str, np.ndarray]:
    c, h = obj.bbox_local()
    a = approach_local / np.linalg.norm(approach_local)
    left = np.array([-a[1], a[0], 0.0])
    top = objs.top_height_local(obj)
    along = rng.uniform(-0.1, 0.1) * abs(a @ h)
    out = {}
    for limb, sgn in (("left_foot", 1.0), ("right_foot", -1.0)):
        p = c + along * a + sgn * dims.stance_w * left
        p[2] = top
        out[limb] = _local_to_world(obj, p)
    return out


def _place_on(obj_cls, size, support: ObjectGeometry, rng):
    """World position and yaw of an object of ``obj_cls`` resting on ``support``'s top."""
    c, h = support.bbox_local()
    top = objs.top_height_local(support)
    room = np.maximum(h[:2] - np.asarray(size[:2]) / 2 - 0.03, 0.0)
    xy = c[:2] + rng.uniform(-0.5, 0.5, 2) * room
    p_local = np.array([xy[0], xy[1], top + objs.bottom_offset(obj_cls, size)])
    pos = support.to_world(p_local)[0]
    yaw = frames.quat_to_yaw(support.quat) + rng.uniform(-0.2, 0.2)
    return pos, yaw


def _approach_for(obj: ObjectGeometry, action: str, rng) -> np.ndarray:
    """Direction (object frame) the person faces when doing ``action`` on ``obj``."""
    cls = obj.object_class
    if cls == "trolley":
        return np.array([1.0, 0.0, 0.0])  # from the handle (rear), pushing along +x
    if cls in ("shelf", "table", "basket"):
        return np.array([1.0, 0.0, 0.0])  # from the front (-x side)
    k = rng.integers(4)
    return np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]][k])


@dataclass
class Composition:
    objects: dict[str, ObjectGeometry]
    hands: dict[str, HandTarget]
    hand_object: dict[str, str]
    soles: dict[str, np.ndarray] | None
    sole_object: str | None
    approach_yaw: float
    dims: BodyDims


def compose(subtask: Subtask, rng: np.random.Generator, reference_sizes: dict | None = None,
            size_range: float = 0.2) -> Composition:  # fmt: skip
    """Objects, limb targets and body dimensions for one subtask."""
    ref = reference_sizes or {}
    dims = BodyDims(rng.uniform(1.62, 1.88))
    inter = list(subtask.interactions)
    refs = dict((c, p) for p, c in subtask.references)
    classes = subtask.object_classes
    sizes = {c: _instance_size(c, ref, rng, size_range) for c in classes}
    colours = {c: objs.palette(rng) for c in classes}
    world_yaw = rng.uniform(-np.pi, np.pi)
    placed: dict[str, ObjectGeometry] = {}

    def make(cls, pos, yaw):
        o = objs.make_object(cls, cls, sizes[cls], colours[cls], pos, yaw)
        placed[cls] = o
        return o

    step = next((i for i in inter if i.action == "step"), None)
    reach = [i for i in inter if i.action != "step"]
    hands, hand_obj, soles, sole_obj = {}, {}, None, None
    if step is not None and reach:
        # reach something high while standing on the step object: the reached object sits on a shelf
        tgt_cls = reach[0].object_class
        if tgt_cls not in ("shelf", "table", "trolley") and "shelf" not in sizes:
            sizes["shelf"], colours["shelf"] = _instance_size("shelf", ref, rng, size_range), objs.palette(rng)
        support_cls = tgt_cls if tgt_cls in ("shelf", "table", "trolley") else "shelf"
        support = make(support_cls, [0.0, 0.0, 0.0], world_yaw)
        if tgt_cls != support_cls:
            sc, sh = support.bbox_local()
            d_t = sizes[tgt_cls][0]
            p_local = np.array([sc[0] - sh[0] + 0.03 + d_t / 2, 0.0, objs.top_height_local(support)
                                + objs.bottom_offset(tgt_cls, sizes[tgt_cls])])  # fmt: skip
            target = make(tgt_cls, support.to_world(p_local)[0], world_yaw + rng.uniform(-0.1, 0.1))
        else:
            target = support
        sc, sh = support.bbox_local()
        d_s = sizes[step.object_class]
        gap = rng.uniform(0.02, 0.08)
        p_local = np.array([sc[0] - sh[0] - gap - d_s[0] / 2, rng.uniform(-0.05, 0.05),
                            objs.bottom_offset(step.object_class, d_s)])  # fmt: skip
        stepobj = make(step.object_class, support.to_world(p_local)[0], world_yaw + rng.uniform(-0.15, 0.15))
        approach_yaw = world_yaw
        a_step = stepobj.R.T @ np.array([np.cos(approach_yaw), np.sin(approach_yaw), 0.0])
        soles = _sole_contacts(stepobj, a_step, dims, rng)
        sole_obj = stepobj.id
        a_tgt = target.R.T @ np.array([np.cos(approach_yaw), np.sin(approach_yaw), 0.0])
        hands = _hand_contacts(reach[0].action, target, a_tgt, rng)
        hand_obj = {k: target.id for k in hands}
    elif step is not None:
        obj = make(step.object_class, [0.0, 0.0, objs.bottom_offset(step.object_class, sizes[step.object_class])],
                   world_yaw)  # fmt: skip
        a_loc = _approach_for(obj, "step", rng)
        approach_yaw = world_yaw + np.arctan2(a_loc[1], a_loc[0])
        soles = _sole_contacts(obj, a_loc, dims, rng)
        sole_obj = obj.id
    else:
        it: Interaction = reach[0]
        cls = it.object_class
        support_cls = next((c for c, p in refs.items() if p in ("from", "on", "onto", "on top of", "into")), None)
        beside_cls = next((c for c, p in refs.items() if p in ("next to", "near", "beside", "to", "in front of")), None)
        if support_cls and support_cls != cls:
            support = make(support_cls, [0.0, 0.0, 0.0], world_yaw)
            pos, yaw = _place_on(cls, sizes[cls], support, rng)
            target = make(cls, pos, yaw)
            a_sup = _approach_for(support, it.action, rng)
            if support.object_class == "trolley":  # load a trolley from its side
                a_sup = np.array([0.0, rng.choice([-1.0, 1.0]), 0.0])
            a_world = support.R @ a_sup
        else:
            target = make(cls, [0.0, 0.0, objs.bottom_offset(cls, sizes[cls])], world_yaw)
            a_world = target.R @ _approach_for(target, it.action, rng)
            if beside_cls and beside_cls != cls:
                bsize = sizes[beside_cls]
                lateral = np.array([-a_world[1], a_world[0], 0.0]) * rng.choice([-1.0, 1.0])
                dist = 0.5 * (np.max(sizes[cls][:2]) + np.max(bsize[:2])) + rng.uniform(0.05, 0.15)
                make(beside_cls, target.pos * [1, 1, 0] + dist * lateral, world_yaw + rng.uniform(-0.3, 0.3))
        approach_yaw = float(np.arctan2(a_world[1], a_world[0]))
        hands = _hand_contacts(it.action, target, target.R.T @ a_world, rng)
        hand_obj = {k: target.id for k in hands}
    return Composition(placed, hands, hand_obj, soles, sole_obj, approach_yaw, dims)


# ------------------------------------------------------------------------------------------------
# rendering


def _build_model(comp: Composition, capsules, rng, width, height, fovy, cam_pos, cam_target):
    spec = mujoco.MjSpec()
    spec.visual.global_.offwidth = width
    spec.visual.global_.offheight = height
    spec.visual.quality.shadowsize = 0
    spec.visual.quality.offsamples = 0
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]
    spec.visual.map.znear = 0.01
    spec.stat.extent = 5.0
    tex = spec.add_texture()
    tex.name = "floor_tex"
    tex.type = mujoco.mjtTexture.mjTEXTURE_2D
    tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
    g = rng.uniform(0.35, 0.75)
    tint = rng.uniform(-0.08, 0.08, 3)
    tex.rgb1 = list(np.clip(g + tint, 0, 1))
    tex.rgb2 = list(np.clip(g - 0.08 + tint, 0, 1))
    tex.width = tex.height = 256
    mat = spec.add_material()
    mat.name = "floor_mat"
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "floor_tex"
    mat.texrepeat = [2.0, 2.0]
    mat.texuniform = True
    wb = spec.worldbody
    floor = wb.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [8, 8, 0.05]
    floor.material = "floor_mat"
    light = wb.add_light()
    light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    light.pos = [0, 0, 5]
    light.dir = list(np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), -1.0]))
    light.diffuse = [0.55, 0.55, 0.55]
    light.castshadow = False
    names = []
    for name, obj in comp.objects.items():
        body = wb.add_body()
        body.name = name
        body.pos = list(obj.pos)
        body.quat = list(obj.quat)
        for i, p in enumerate(obj.primitives):
            geom = body.add_geom()
            geom.name = f"{name}/{i}"
            geom.type = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
                         "sphere": mujoco.mjtGeom.mjGEOM_SPHERE, "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE}[p.type]
            geom.size = list(p.size) + [0.0] * (3 - len(p.size))
            geom.pos = list(p.pos)
            geom.quat = list(p.quat)
            geom.rgba = list(p.rgba or (0.6, 0.6, 0.6, 1.0))
        names.append(name)
    for cname, a, b, r, rgba in capsules:
        geom = wb.add_geom()
        geom.name = f"person/{cname}"
        geom.rgba = list(rgba)
        if np.linalg.norm(b - a) < 1e-6:
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.size = [r, 0, 0]
            geom.pos = list(a)
        else:
            geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
            geom.fromto = [*a, *b]
            geom.size = [r, 0, 0]
    cam = wb.add_camera()
    cam.name = "demo_camera"
    cam.pos = list(cam_pos)
    cam.quat = list(frames.look_at_mujoco_camera_quat(cam_pos, cam_target))
    cam.fovy = float(fovy)
    return spec.compile(), names


class SyntheticImageGenerator:
    """Offline stand-in of the text-to-image LDM (see module docstring)."""

    name = "synthetic"

    def __init__(self, width: int = 1024, height: int = 1024, fovy_deg=(45.0, 60.0), elevation_deg=(8.0, 32.0),
                 azimuth_deg=(35.0, 145.0), size_range: float = 0.2, with_person: bool = True,
                 max_reach_error: float = 0.03):  # fmt: skip
        self.width, self.height = int(width), int(height)
        self.fovy_deg = tuple(fovy_deg)
        self.elevation_deg = tuple(elevation_deg)
        self.azimuth_deg = tuple(azimuth_deg)
        self.size_range = float(size_range)
        self.with_person = bool(with_person)
        self.max_reach_error = float(max_reach_error)
        self._lock = threading.Lock()

    def generate(self, request: GenerationRequest) -> PerceptionImage:
        if request.subtask is None:
            raise PerceptionError(INVALID_REQUEST, "the synthetic generator needs the parsed subtask")
        width = int(request.width or self.width)
        height = int(request.height or self.height)
        for attempt in range(4):
            rng = np.random.default_rng([int(request.seed) & 0xFFFFFFFF, attempt])
            comp = compose(request.subtask, rng, request.reference_sizes, self.size_range)
            soles = comp.soles
            sk, err = solve_pose(comp.dims, comp.approach_yaw, comp.hands, soles, list(comp.objects.values()), 0.0, rng)
            if err <= self.max_reach_error:
                break
        return self._render(request, comp, sk, err, rng, width, height)

    def _render(self, request, comp: Composition, sk, reach_err, rng, width, height) -> PerceptionImage:
        capsules = body_capsules(comp.dims, sk, random_appearance(rng)) if self.with_person else []
        pts = [sk.points[k] for k in KEYPOINTS] if self.with_person else []
        for o in comp.objects.values():
            c, h = o.bbox_local()
            pts += list(o.to_world(c + h * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])))
        pts = np.array(pts)
        centre = (pts.min(0) + pts.max(0)) / 2
        radius = float(np.max(np.linalg.norm(pts - centre, axis=1)))
        fovy = rng.uniform(*self.fovy_deg)
        half = np.deg2rad(fovy) / 2 * min(1.0, width / height)
        dist = radius / np.sin(half) * rng.uniform(0.92, 1.08)
        az = comp.approach_yaw + np.deg2rad(rng.uniform(*self.azimuth_deg)) * rng.choice([-1.0, 1.0])
        el = np.deg2rad(rng.uniform(*self.elevation_deg))
        cam_pos = centre + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        model, names = _build_model(comp, capsules, rng, width, height, fovy, cam_pos, centre)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with self._lock:
            renderer = mujoco.Renderer(model, height, width)
            try:
                renderer.update_scene(data, "demo_camera")
                rgb = renderer.render().copy()
                renderer.enable_depth_rendering()
                renderer.update_scene(data, "demo_camera")
                depth = renderer.render().astype(np.float32)
                renderer.disable_depth_rendering()
                renderer.enable_segmentation_rendering()
                renderer.update_scene(data, "demo_camera")
                seg = renderer.render()[..., 0].copy()
            finally:
                renderer.close()
        geom_label = np.full(model.ngeom, BACKGROUND, np.int16)
        for g in range(model.ngeom):
            gname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            if gname == "floor":
                geom_label[g] = FLOOR
            elif gname.startswith("person/"):
                geom_label[g] = PERSON
            elif "/" in gname:
                geom_label[g] = 2 + names.index(gname.split("/")[0])
        labels = np.where(seg >= 0, geom_label[np.clip(seg, 0, None)], BACKGROUND).astype(np.int16)
        depth[labels == BACKGROUND] = np.inf
        cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "demo_camera")
        _, R_opt = frames.mujoco_camera_to_optical(data.cam_xpos[cid], data.cam_xmat[cid].reshape(3, 3))
        cam_pose = RigidPose(R_opt, data.cam_xpos[cid].copy())
        camera = PinholeCamera.from_fovy(width, height, fovy)
        kp_world = {k: sk.points[k].copy() for k in KEYPOINTS} if self.with_person else {}
        visible = {}
        for k, p in kp_world.items():
            pc = cam_pose.inverse_apply(p)[0]
            if pc[2] <= 0:
                visible[k] = False
                continue
            u, v = np.round(camera.project(pc)[0]).astype(int)
            visible[k] = bool(0 <= u < width and 0 <= v < height and labels[v, u] == PERSON
                              and abs(depth[v, u] - pc[2]) < 0.12)  # fmt: skip
        contacts = []
        if self.with_person:
            for limb, t in comp.hands.items():
                o = comp.objects[comp.hand_object[limb]]
                contacts.append(GTContact(limb, o.id, t.contact, t.normal, o.canonical(t.contact)[0]))
            if comp.soles:
                o = comp.objects[comp.sole_object]
                for limb, p in comp.soles.items():
                    contacts.append(GTContact(limb, o.id, p, o.R @ np.array([0, 0, 1.0]), o.canonical(p)[0]))
        gt = DemoGroundTruth(request.subtask, comp.objects, camera, cam_pose, fovy, depth, labels, names, kp_world,
                             visible, contacts, self.with_person, reach_err, int(request.seed))  # fmt: skip
        return PerceptionImage(rgb=rgb, ground_truth=gt, source="synthetic generator")


@register("image_generator", "synthetic")
def _factory(**params) -> SyntheticImageGenerator:
    return SyntheticImageGenerator(**params)
