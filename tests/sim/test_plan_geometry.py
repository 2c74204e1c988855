"""lomanip_sim.plan_geometry: the plan's configurations against the simulator's meshes."""

from dataclasses import replace

import numpy as np
from to_cases import simulation

from lomanip_sim.plan_geometry import plan_penetrations
from lomanip_sim.robot_model import G1_JOINT_NAMES


def test_standing_plan_overlaps_nothing_and_leaves_the_sim_alone():
    sim, tr = simulation("case_stand")
    before = sim.data.qpos.copy()
    assert plan_penetrations(sim, tr) == []
    assert np.array_equal(sim.data.qpos, before)


def test_crossed_thighs_are_a_self_overlap():
    sim, tr = simulation("case_stand")
    q = tr.q.copy()
    q[:, G1_JOINT_NAMES.index("left_hip_roll_joint")] = -0.4  # both thighs turned inwards
    q[:, G1_JOINT_NAMES.index("right_hip_roll_joint")] = 0.4
    out = plan_penetrations(sim, replace(tr, q=q), min_depth=0.01)
    assert out and all(p.kind == "self" for p in out)
    assert any("left_" in p.robot_body and "right_" in p.other or "right_" in p.robot_body and "left_" in p.other
               for p in out)
    assert out == sorted(out, key=lambda p: -p.depth)


def test_a_base_moved_into_the_table_is_a_body_overlap_and_the_planned_grasp_is_not():
    sim, tr = simulation("case_lift_box")
    held = plan_penetrations(sim, tr, min_depth=0.005)
    assert not [p for p in held if p.kind == "body"]
    grasp = [ph for ph in tr.phases if any(c.object_id == "box" for c in ph.contacts.values())]
    t0, t1 = grasp[0].start, grasp[-1].end
    # the hands on the box while the schedule has them there are the plan's contact, not an overlap
    assert not [p for p in held if p.other == "box" and t0 < p.t < t1]
    base = tr.base_pos.copy()
    base[:, 0] += 0.35  # the table is 0.42 m ahead of the pelvis
    moved = plan_penetrations(sim, replace(tr, base_pos=base), min_depth=0.005)
    into_table = [p for p in moved if p.kind == "body" and p.other == "table"]
    assert into_table and into_table[0].depth > 0.05
