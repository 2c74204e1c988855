"""Task success per scenario, measured from the physics state at the end of an execution.

Definitions (also in docs/execution.md):

* S1 basket retrieval (``s1_basket``): the basket's frame is at least ``S1_MIN_LIFT`` (0.10 m) above
  its initial (shelf) position, AND both foot sites are on the box top (foot site height within
  1-6 cm above the box top, foot xy inside the box footprint), AND the robot has not fallen.
* S2 trolley (``s2_trolley``): the box rests on the trolley deck (box bottom within 3 cm of the deck
  top, box centre inside the deck footprint, box speed relative to the trolley below 0.1 m/s), AND
  the trolley moved forward along its initial heading by the planned distance within
  max(5 cm, 25 % of it), AND the robot has not fallen. A plan of part of S2 is judged on its part:
  where the plan does not move the box (a push-only task, e.g. ``make demo``'s), the box must stay
  within 5 cm of where it was instead of being on the deck; where it does not move the trolley,
  the trolley must stay within 5 cm.
* Any other plan (test cases): the robot has not fallen, its final pelvis position is within
  0.10 m of the plan's final one, and every object the plan moves ends within 0.05 m of its planned
  final position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import frames
from .trajectory import Trajectory

S1_MIN_LIFT = 0.10
S2_DECK_TOL = 0.03
S2_MIN_DIST_TOL = 0.05
S2_REL_DIST_TOL = 0.25
S2_UNPLANNED_TOL = 0.05   # an object the plan does not move may drift this much
GENERIC_BASE_TOL = 0.10
GENERIC_OBJECT_TOL = 0.05


@dataclass(frozen=True)
class TaskOutcome:
    success: bool
    detail: str


def _top_box(info):
    """(centre xy, half extents xy, top z) of an object's largest horizontal box primitive, object frame."""
    boxes = [p for p in info.primitives if p.type == "box"]
    if not boxes:
        return None
    p = max(boxes, key=lambda b: b.size[0] * b.size[1])
    return np.asarray(p.pos[:2]), np.asarray(p.size[:2]), float(p.pos[2] + p.size[2])


def _inside(sim, oid: str, point: np.ndarray, margin: float = 0.0) -> tuple[bool, float]:
    """Is world ``point`` over the top box of object ``oid``? Returns (inside xy, height above its top)."""
    st = sim.object_state(oid)
    top = _top_box(sim.world.objects[oid])
    R = frames.quat_to_matrix(st.quat)
    local = R.T @ (np.asarray(point) - st.pos)
    if top is None:
        return False, float("nan")
    c, h, zt = top
    return bool(np.all(np.abs(local[:2] - c) <= h + margin)), float(local[2] - zt)


def evaluate(sim, traj: Trajectory, initial_objects: dict, fell: bool) -> TaskOutcome:
    """Task success for the plan's scenario from ``sim``'s current state."""
    objs = sim.world.objects
    if traj.scenario == "s1_basket" and {"basket", "box"} <= set(objs):
        return _s1(sim, initial_objects, fell)
    if traj.scenario == "s2_trolley" and {"box", "trolley"} <= set(objs):
        return _s2(sim, traj, initial_objects, fell)
    return _generic(sim, traj, fell)


def _s1(sim, initial, fell) -> TaskOutcome:
    lift = float(sim.object_pose("basket")[0][2] - initial["basket"][0][2])
    feet_ok, notes = True, []
    from .robot_model import FOOT_SITES

    for side, site in FOOT_SITES.items():
        inside, h = _inside(sim, "box", sim.site_position(site))
        ok = inside and 0.01 <= h <= 0.06
        feet_ok &= ok
        notes.append(f"{side} foot {'on' if ok else 'NOT on'} the box (height above top {h * 100:.1f} cm)")
    ok = lift >= S1_MIN_LIFT and feet_ok and not fell
    return TaskOutcome(ok, f"S1: basket lifted {lift * 100:.1f} cm (need >= {S1_MIN_LIFT * 100:.0f}); "
                       + "; ".join(notes) + ("; robot fell" if fell else ""))


def _planned_displacement(traj: Trajectory, oid: str) -> np.ndarray:
    if oid not in traj.objects:
        return np.zeros(3)
    p = traj.objects[oid][0]
    return np.asarray(p[-1] - p[0], float)


def _s2(sim, traj: Trajectory, initial, fell) -> TaskOutcome:
    box, trolley = sim.object_state("box"), sim.object_state("trolley")
    notes = []
    if np.linalg.norm(_planned_displacement(traj, "box")) > S2_UNPLANNED_TOL:
        bottom = box.pos.copy()
        bt = _top_box(sim.world.objects["box"])
        if bt is not None:
            bottom[2] -= bt[2]  # box frame at its centre: top z = half height
        inside, h = _inside(sim, "trolley", bottom, margin=0.0)
        rel_speed = float(np.linalg.norm(box.linvel - trolley.linvel))
        box_ok = inside and abs(h) <= S2_DECK_TOL and rel_speed < 0.1
        notes.append(f"box {'on' if box_ok else 'NOT on'} the trolley (bottom {h * 100:.1f} cm from the deck, "
                     f"inside={inside}, relative speed {rel_speed:.2f} m/s)")
    else:
        drift = float(np.linalg.norm(box.pos - initial["box"][0]))
        box_ok = drift <= S2_UNPLANNED_TOL
        notes.append(f"box not moved by the plan, {drift * 100:.1f} cm from where it was "
                     f"(tolerance {S2_UNPLANNED_TOL * 100:.0f} cm)")
    p0, q0 = initial["trolley"]
    heading = frames.quat_to_matrix(q0)[:, 0]
    moved = float((trolley.pos - p0) @ heading)
    planned = float(_planned_displacement(traj, "trolley") @ heading)
    if planned > S2_UNPLANNED_TOL:
        tol = max(S2_MIN_DIST_TOL, S2_REL_DIST_TOL * abs(planned))
        trolley_ok = abs(moved - planned) <= tol
        notes.append(f"trolley moved {moved:.2f} m forward, planned {planned:.2f} m (tolerance {tol:.2f} m)")
    else:
        drift = float(np.linalg.norm(trolley.pos - p0))
        trolley_ok = drift <= S2_UNPLANNED_TOL
        notes.append(f"trolley not pushed by the plan, {drift * 100:.1f} cm from where it was "
                     f"(tolerance {S2_UNPLANNED_TOL * 100:.0f} cm)")
    ok = box_ok and trolley_ok and not fell
    return TaskOutcome(ok, "S2: " + "; ".join(notes) + ("; robot fell" if fell else ""))


def _generic(sim, traj: Trajectory, fell) -> TaskOutcome:
    eb = float(np.linalg.norm(sim.base_pose()[0] - traj.base_pos[-1]))
    notes = [f"final pelvis {eb * 100:.1f} cm from the plan (tolerance {GENERIC_BASE_TOL * 100:.0f} cm)"]
    ok = not fell and eb <= GENERIC_BASE_TOL
    for oid, (p, _q) in traj.objects.items():
        if oid not in sim.world.objects:
            continue
        e = float(np.linalg.norm(sim.object_pose(oid)[0] - p[-1]))
        ok &= e <= GENERIC_OBJECT_TOL
        notes.append(f"{oid} {e * 100:.1f} cm from its planned final position (tolerance {GENERIC_OBJECT_TOL * 100:.0f} cm)")
    return TaskOutcome(bool(ok), f"plan '{traj.scenario or 'unnamed'}': " + "; ".join(notes) + ("; robot fell" if fell else ""))
