"""Two-handed squeeze grasps: the transferred hand contacts made antipodal through the object's CoM.

Why: the contact transfer places each hand where the person's hand was, independently, so the two
points of a squeeze are neither opposite each other nor level with the object's CoM. S2's pick came
out with the hands 2.5 and 4.8 cm behind the box's CoM along its faces and at 5.8 and 8.9 cm above
its centre (of a 12.5 cm half height). Gravity acting off the line through both contacts twists the
object about that line, which only the patches' torsional friction resists: executed, the box
turned and slid 3 cm each way between the hands before the lift (docs/execution.md, session 34).
The hand-written fixtures that execute grip opposite each other, level with the centre.

So for two hands on opposite side faces of one movable object (a departure from the paper, which
keeps the transferred points):

* the horizontal coordinate along the faces becomes the CoM's (no moment about the grasp line);
* both hands take one common height, their mean, kept ``HAND_FACE_EDGE_MARGIN`` below the top and
  above the bottom (a hand high on a face gripped its top edge);
* each keeps its face (its coordinate along the normal) and its normal.

Any other contact set (one hand, two objects, a rolling object, faces not opposite) is no squeeze
(None). The planner falls back to the transferred points when the IK cannot reach the antipodal
ones (S1's basket, high on its shelf, seen from the box top).

Off by default (``keyframes.ANTIPODAL_SQUEEZE``): on S2's generated pick and carry it did not stop
the fall under physics, and over the grids it balanced one loaded keyframe fewer (session 35).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np

from lomanip_to.model import quat_xyzw_to_rot
from lomanip_to.problem import SceneObject

from .retargeting import HANDS, LimbTarget

#: a squeezing hand's contact point stays this far inside its face's top and bottom edges (m): about
#: the G1 hand's half height, so the hand's patch stays on the face
HAND_FACE_EDGE_MARGIN = 0.05
#: the two normals are opposite when their dot product is below minus this
OPPOSITE_COS = 0.95
#: a side face's normal has a vertical component of at most this
SIDE_FACE_MAX_Z = 0.3


def antipodal_squeeze(contacts: Sequence[LimbTarget], objects: Mapping[str, SceneObject],
                      rolling: frozenset = frozenset()) -> list[LimbTarget] | None:
    """``contacts`` with their two-handed squeeze moved along its faces (module docstring), or
    None if they hold no squeeze; contacts are in the frame ``objects`` give their objects' poses in."""
    contacts = list(contacts)
    hands = [i for i, c in enumerate(contacts) if c.limb in HANDS]
    if len(hands) != 2:
        return None
    a, b = (contacts[i] for i in hands)
    obj = objects.get(a.object_id)
    if a.object_id != b.object_id or obj is None or not obj.movable or obj.id in rolling or not obj.primitives:
        return None
    R = quat_xyzw_to_rot(obj.quat_xyzw)
    origin = np.asarray(obj.position, float)
    na, nb = (R.T @ (np.asarray(c.normal, float) / np.linalg.norm(c.normal)) for c in (a, b))
    if float(na @ nb) > -OPPOSITE_COS or max(abs(na[2]), abs(nb[2])) > SIDE_FACE_MAX_Z:
        return None
    axis = np.array([na[0] - nb[0], na[1] - nb[1], 0.0])
    axis /= np.linalg.norm(axis)
    along = np.cross([0.0, 0.0, 1.0], axis)
    local = [R.T @ (np.asarray(c.position, float) - origin) for c in (a, b)]
    top, bottom = obj.top_z(), obj.bottom_z()
    z = float(np.mean([p[2] for p in local]))
    if top - bottom > 2.0 * HAND_FACE_EDGE_MARGIN:
        z = float(np.clip(z, bottom + HAND_FACE_EDGE_MARGIN, top - HAND_FACE_EDGE_MARGIN))
    else:
        z = 0.5 * (top + bottom)
    com = np.asarray(obj.com, float)
    for i, p in zip(hands, local):
        q = float(p @ axis) * axis + float(com @ along) * along + np.array([0.0, 0.0, z])
        contacts[i] = replace(contacts[i], position=origin + R @ q)
    return contacts
