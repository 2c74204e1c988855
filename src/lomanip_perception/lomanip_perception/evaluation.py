"""Evaluation against synthetic ground truth (DESIGN.md Sec. 7: contact transfer = distance between
transferred and ground-truth contact points, median and p90), and scene helpers for offline use.

Ground truth of a transferred contact: the demonstration's true contact point, expressed in the
canonical (bounding-box normalised) coordinates of the demo object, mapped to the same canonical
coordinates of the scene object and projected onto its surface: "the same place on this instance".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .datatypes import PerceptionImage, PinholeCamera, RigidPose
from .pipeline import FLOOR_ID, SceneInput, SubtaskResult
from .scene import ObjectGeometry, Primitive


def object_from_state(state) -> ObjectGeometry:
    """lomanip_sim.simulator.ObjectState -> ObjectGeometry."""
    prims = tuple(Primitive(p.type, tuple(p.size), np.asarray(p.pos, float), np.asarray(p.quat, float))
                  for p in state.primitives)  # fmt: skip
    return ObjectGeometry(state.id, state.object_class, np.asarray(state.pos, float), np.asarray(state.quat, float),
                          prims, bool(state.movable))  # fmt: skip


def sim_scene(scenario: str = "s1_basket", overrides: dict | None = None) -> SceneInput:
    """Render the scenario's scene camera once (G1 standing, objects at rest) as a SceneInput."""
    import lomanip_sim  # noqa: F401
    from lomanip_sim.camera import RGBDCamera
    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.simulator import Simulation

    sim = Simulation(load_scenario(scenario, overrides or {}))
    with RGBDCamera(sim.model, sim.world.camera_name) as cam:
        frame = cam.render(sim.snapshot().qpos, 0.0)
    k = frame.intrinsics
    image = PerceptionImage(frame.rgb, frame.depth, PinholeCamera(k.width, k.height, k.fx, k.fy, k.cx, k.cy),
                            RigidPose(frame.pose.R_optical, frame.pose.position), source="simulator")  # fmt: skip
    return SceneInput(image, [object_from_state(o) for o in sim.scene_objects()])


@dataclass(frozen=True)
class ContactError:
    subtask: int
    limb: str
    object_id: str
    object_class: str
    error: float  # metres, after surface projection
    error_raw: float  # metres, before surface projection
    predicted: np.ndarray
    truth: np.ndarray


def contact_errors(result: SubtaskResult, demo: PerceptionImage, scene: SceneInput) -> list[ContactError]:
    """Errors of the object contacts of one subtask against the demo's ground truth."""
    gt = demo.ground_truth
    by_id = {o.id: o for o in scene.objects}
    truth = {c.limb: c for c in gt.contacts}
    out = []
    for c in result.contacts:
        if c.object_id == FLOOR_ID or c.limb not in truth:
            continue
        obj = by_id[c.object_id]
        g = truth[c.limb]
        p_true, _ = obj.project_to_surface(obj.from_canonical(g.canonical))
        raw = result.raw_points.get(c.limb, c.position)
        out.append(ContactError(result.index, c.limb, c.object_id, obj.object_class,
                                float(np.linalg.norm(c.position - p_true[0])), float(np.linalg.norm(raw - p_true[0])),
                                c.position, p_true[0]))  # fmt: skip
    return out
