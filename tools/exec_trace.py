#!/usr/bin/env python3
"""Trace of one execution under physics: what the robot, its hands and the carried object do against the plan.

Why: a run that falls says where (metrics.json) but not why. This steps the same execution as
tools/bench_exec.py and prints, every --every seconds of trajectory time between --start and
--stop: each movable object's position error against its plan; per hand its tracking error, the
measured contact force and, while the plan has it on an object, its position in that object's
frame; the CoM and pelvis errors; each foot's measured force and, for a loaded foot, its centre of
pressure in the foot frame (the sole spans the contact spheres, x -0.05..0.12 m, y -0.03..0.03 m;
a centre of pressure on that edge means the foot is about to roll). docs/execution.md (session 29)
reads S2's carry with it. ``--cop`` adds the centre of pressure the controller's QP chose for each
stance sole (is a sole on its edge asked for, or pushed there?); ``--grip`` adds every contact of
a hand's arm on the object the plan has it hold (where on the box each hand presses, and how near
to sliding: tangential over normal force against the friction coefficient); ``--joints`` adds the
named joints' measured and planned angles, ranges and torques against their limits (a leg at its
torque limit in S1's step onto the box, docs/execution.md session 50). ``--guard`` adds the
controller's active barrier rows (a hand held off its hip or off the handle, session 60).

    .venv/bin/python tools/exec_trace.py runs/bench_to/s2_trolley_mass2.5_yaw0_all.npz --start 4 --stop 6.5
    .venv/bin/python tools/exec_trace.py <npz> --gains '{"grasp_squeeze_scale": 2.0}'
    .venv/bin/python tools/exec_trace.py <npz> --start 4.8 --stop 5.2 --every 0.04 --cop --grip
    .venv/bin/python tools/exec_trace.py <npz> --start 13.8 --stop 14.5 --joints right_hip_pitch_joint,right_knee_joint
    .venv/bin/python tools/exec_trace.py runs/bench_push/base --perturb closer   # a tools/bench_push.py case
    .venv/bin/python tools/exec_trace.py runs/s2_pick_carry/s2_trolley.npz        # a tools/plan_structure.py --solve
    .venv/bin/python tools/exec_trace.py runs/20261206-041500                     # a `make demo` / `lomanip plan` run
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for _p in ("tools", "src/lomanip_sim", "src/lomanip_to"):
    sys.path.insert(0, str(ROOT / _p))


def _touching(model, data, body: int) -> list[str]:
    """Names of the bodies other than the world (floor) that ``body``'s geoms touch now."""
    import mujoco

    out = set()
    for c in data.contact[: data.ncon]:
        b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
        other = b2 if b1 == body else b1 if b2 == body else None
        if other is not None and other != 0:
            out.add(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, other))
    return sorted(out)


def _object_contacts(ex) -> str:
    """Each robot link's total contact force on each scene object (not the floor) and on another of
    its links, largest first."""
    from lomanip_sim.contact_forces import contact_force_totals

    m, d = ex.sim.model, ex.sim.data
    robot = m.body_rootid[ex.wbc.pelvis]

    def key(b1: int, b2: int):
        if m.body_rootid[b1] == robot and m.body_rootid[b2] == robot:  # the robot on itself
            return m.body(b1).name, m.body(b2).name
        for mine, other in ((b1, b2), (b2, b1)):
            if m.body_rootid[mine] == robot and other != 0 and m.body_rootid[other] != robot:
                return m.body(mine).name, m.body(int(m.body_rootid[other])).name
        return None

    totals = {k: float(np.linalg.norm(f)) for k, f in contact_force_totals(m, d, key).items()}
    return " ".join(f"[{a} on {b} {f:.0f} N]" for (a, b), f in sorted(totals.items(), key=lambda kv: -kv[1]))


def trace_line(ex, objects: list[str], cop: bool = False, grip: bool = False, contacts: bool = False,
               joints: tuple[str, ...] = (), guard: bool = False) -> str:
    """One line of the trace at the execution's current time; ``cop``: each stance sole's centre of
    pressure as the controller's QP chose it beside the measured one; ``grip``: each contact of a
    hand's arm on the object the plan has it hold (link, point in the object body's frame, normal
    and tangential force); ``contacts``: every robot link's contact force on a scene object or another link."""
    import mujoco

    from lomanip_sim.contact_forces import arm_contacts_on, centre_of_pressure_in_body
    from lomanip_sim.trajectory import FEET, HANDS

    sim, tr, w = ex.sim, ex.traj, ex.wbc
    m, d = sim.model, sim.data
    t = ex.time
    i, s = tr.index_at(min(t, tr.duration))

    def lerp(a):
        return a[i] + s * (a[i + 1] - a[i])

    parts = [f"t={t:5.2f}"]
    frames = {}
    for oid in objects:
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, sim.world.objects[oid].body_name)
        R = d.xmat[b].reshape(3, 3)
        frames[oid] = (d.xpos[b] + R @ w._com_offset(b), R)
        parts.append(f"{oid} err {np.round(frames[oid][0] - lerp(tr.objects[oid][0]), 3)}")
    phase = tr.phase_at(min(t, tr.duration))
    for h in HANDS:
        ph = d.site_xpos[w.site_id[h]]
        line = f"{h[0]}h err {np.round(ph - lerp(w.refs.site_p[h]), 3)} f {np.linalg.norm(w.measured_forces[h]):4.0f}"
        c = phase.contacts.get(h) if phase is not None else None
        if c is not None and c.object_id in frames:  # where the hand is on the object it holds in the plan
            p, R = frames[c.object_id]
            line += f" in {c.object_id} {np.round(R.T @ (ph - p), 3)}"
            if grip:
                body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, sim.world.objects[c.object_id].body_name)
                line += "".join(f" [{link} {np.round(q, 3)} fn {fn:3.0f} ft {ft:3.0f}]"
                                for link, q, fn, ft in arm_contacts_on(m, d, h.split("_")[0], body))
        if h in w._push_force:  # pushing a floor object: desired normal force, admittance shift along the normal
            n, f_des = w._push_force[h]
            line += f" fn {float(n @ w.measured_forces[h]):4.0f}/{f_des:3.0f} adm {100 * w._admittance[h][1]:4.1f}cm"
        reg = w.registered_shifts.get(h)
        if reg is not None and np.any(reg != 0.0):  # hand_registered_after_release: the reference's shift
            line += f" reg {np.round(reg, 3)}"
        hand_body = int(m.site_bodyid[w.site_id[h]])
        line += "".join(f" on {name}" for name in _touching(m, d, hand_body))
        parts.append(line)
    com, pel = d.subtree_com[w.pelvis], d.xpos[w.pelvis]
    parts.append(f"com err {np.round(com - lerp(w.refs.com), 3)} pelvis err {np.round(pel - lerp(w.refs.base_p), 3)}")
    for f in FEET:
        planned = "stance" if phase is not None and f in phase.contacts else "swing"
        measured = centre_of_pressure_in_body(m, d, w.foot_body[f])
        cop_s = f" cop {np.round(measured, 3)}" if measured is not None else ""
        asked = w.qp_sole_cop(f) if cop else None
        if asked is not None:
            cop_s += f" qp cop {np.round(asked, 3)}"
        err = d.site_xpos[w.site_id[f]] - lerp(w.refs.site_p[f])
        parts.append(f"{f[0]}f {planned} f {np.linalg.norm(w.measured_forces[f]):4.0f}{cop_s} err {np.round(err, 3)}"
                     + "".join(f" on {name}" for name in _touching(m, d, w.foot_body[f])))
    if joints:  # measured / planned angle (rad), the joint's range, the controller's torque / its limit (N m)
        from lomanip_sim.robot_model import G1_JOINT_NAMES

        q_ref = lerp(tr.q)
        for name in joints:
            j = G1_JOINT_NAMES.index(name)
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            lo, hi = m.jnt_range[jid]
            tau, lim = w._last_tau[j], w.limits[j]
            parts.append(f"{name.removesuffix('_joint')} {d.qpos[m.jnt_qposadr[jid]]:+.3f}/{q_ref[j]:+.3f} [{lo:+.2f},{hi:+.2f}]"
                         f" tau {tau:+5.1f}/{lim:.0f}")
    if guard:   # the controller's barrier rows of the last step: pair, distance, bound on its acceleration
        rows = " ".join(f"[{' / '.join(gr.pair)} {100 * gr.distance:.1f} cm >= {gr.lower:+.1f}]"
                        for gr in ex.wbc.guard_rows)
        parts.append(f"guard {rows or 'none'}")
    if contacts:
        parts.append(f"contacts {_object_contacts(ex) or 'none'}")
    return " | ".join(parts)


def _in_task_world(plan: Path, problem: Path, scenario: str, overrides: dict):
    """(trajectory, simulation) of a saved plan and its pickled problem, in ``scenario``'s world."""
    import pickle

    from lomanip_sim.scenario import load_scenario
    from lomanip_sim.simulator import Simulation
    from lomanip_sim.trajectory import from_to_result
    from lomanip_to.result import TOResult

    with open(problem, "rb") as f:
        prob = pickle.load(f)
    res = TOResult.load(plan)   # densified on load
    return from_to_result(res, prob.phases, scenario=scenario), Simulation(load_scenario(scenario, overrides))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("npz", type=Path, help="a saved TO result (TOResult.save, tools/bench_to.py; one of "
                    "tools/plan_structure.py --solve runs in its task's world), a tools/bench_push.py case "
                    "folder (plan.npz + problem.pkl), or a `lomanip plan` / `make demo` run folder (task.yaml, "
                    "logs/to_problem_<n>.pkl, logs/to_result_<n>.npz)")
    ap.add_argument("--request", type=int, default=1, help="for a run folder: which of its TO requests "
                    "(logs/to_result_<n>.npz)")
    ap.add_argument("--perturb", default="nominal", help="for a bench_push case: its world with this model error "
                    "(bench_push.PERTURBATIONS)")
    ap.add_argument("--problem", help="its fixture (default: the longest config name its file name starts with)")
    ap.add_argument("--start", type=float, default=0.0, help="s of trajectory time")
    ap.add_argument("--stop", type=float, default=float("inf"))
    ap.add_argument("--every", type=float, default=0.1, help="s between lines")
    ap.add_argument("--gains", default="{}", help="WbcGains overrides as JSON")
    ap.add_argument("--cop", action="store_true", help="each stance sole's centre of pressure as the controller's "
                    "QP chose it, beside the measured one")
    ap.add_argument("--contacts", action="store_true", help="every robot link's contact force on a scene object "
                                                           "(not the floor) or on another link, largest first")
    ap.add_argument("--guard", action="store_true", help="the controller's active barrier rows (lomanip_sim."
                    "self_collision_guard): each pair's distance and the bound on its acceleration (m/s^2)")
    ap.add_argument("--grip", action="store_true", help="each contact of a hand's arm on the object it holds: "
                    "link, point in the object body's frame, normal and tangential force")
    ap.add_argument("--joints", default="", help="comma-separated G1 joint names: each one's measured and planned "
                    "angle, its range (rad) and the controller's torque against its limit (N m)")
    ap.add_argument("--world", default=None, help="the plan in a changed world: scenario overrides "
                    "KEY=VALUE[,KEY=VALUE] as tools/bench_exec.py --world (the plan unchanged)")
    args = ap.parse_args()
    from lomanip_sim.robot_model import G1_JOINT_NAMES

    joints = tuple(j.strip() for j in args.joints.split(",") if j.strip())
    unknown = [j for j in joints if j not in G1_JOINT_NAMES]
    if unknown:
        print(f"exec_trace: not G1 joints: {', '.join(unknown)}", file=sys.stderr)
        return 2

    import bench_exec
    from lomanip_sim.execution import Execution
    from lomanip_sim.trajectory import from_to_result
    from lomanip_to import fixtures
    from lomanip_to.result import TOResult

    run_case = args.npz.is_dir() and (args.npz / "task.yaml").is_file()   # a `lomanip plan` / `make demo` run
    push_case = args.npz.is_dir() and not run_case
    if run_case:
        plan_file = args.npz / "logs" / f"to_result_{args.request}.npz"
        if not plan_file.is_file():
            print(f"exec_trace: no such file: {plan_file} (runs before this file was saved cannot be replayed; "
                  "tools/bench_push.py --problems re-solves their logs/to_problem_<n>.pkl)", file=sys.stderr)
            return 2
    elif not (args.npz / "plan.npz" if push_case else args.npz).is_file():
        print(f"exec_trace: no such file: {args.npz}{'/plan.npz' if push_case else ''}", file=sys.stderr)
        return 2
    try:
        gains = bench_exec.gains_from_json(args.gains)
        world = bench_exec.parse_worlds([args.world])[0] if args.world else {}
    except ValueError as e:
        print(f"exec_trace: {e}", file=sys.stderr)
        return 2
    if run_case:
        import yaml

        task = yaml.safe_load((args.npz / "task.yaml").read_text()) or {}
        overrides = {**(task.get("scenario_overrides") or {}), **world}
        traj, sim = _in_task_world(plan_file, args.npz / "logs" / f"to_problem_{args.request}.pkl",
                                   task["scenario"], overrides)
    elif push_case:
        import bench_push

        if args.perturb not in bench_push.PERTURBATIONS:
            print(f"exec_trace: --perturb must be one of {', '.join(bench_push.PERTURBATIONS)}", file=sys.stderr)
            return 2
        task, overrides = bench_push.task_and_overrides(bench_push.CASES.get(args.npz.name))
        overrides = {**bench_push.perturbed(overrides, bench_push.PERTURBATIONS[args.perturb]), **world}
        traj, sim = _in_task_world(args.npz / "plan.npz", args.npz / "problem.pkl", task["scenario"], overrides)
    elif args.npz.with_suffix(".case.yaml").is_file():   # a generated plan saved by tools/plan_structure.py
        import plan_structure
        import yaml

        case = yaml.safe_load(args.npz.with_suffix(".case.yaml").read_text()) or {}
        task = plan_structure.load_task(case["task"])
        overrides = {**(task.get("scenario_overrides") or {}), **(case.get("scenario_overrides") or {}), **world}
        traj, sim = _in_task_world(args.npz, args.npz.with_suffix(".problem.pkl"), task["scenario"], overrides)
    else:
        problem = args.problem or bench_exec._problem_of(args.npz.stem)
        # the grid point it was solved at (a plan traced in the nominal world runs in the wrong scene)
        overrides = bench_exec.saved_overrides(args.npz.parent).get(args.npz.stem, {})
        res = TOResult.load(args.npz)
        task = bench_exec.saved_task(args.npz)   # planned from prompts: its own contact schedule
        prob = (bench_exec.prompts_problem(task, overrides, float(res.t_knots[-1])) if task
                else fixtures.load_problem(problem, overrides))
        if res.t is None:
            res.densify()
        traj = from_to_result(res, prob.phases)
        sim, traj.scenario = bench_exec.plan_world(problem, overrides, prob, traj.qpos(0), world)
        if overrides or world:
            print(f"world: {problem} with {overrides}, simulated with {world}")
    ex = Execution(sim, traj, gains=gains)
    movable = [o for o in traj.objects if o in sim.world.objects and sim.world.objects[o].movable]
    ex.start()
    for d in ex.wbc.detours:  # the hand references the controller shifted before execution
        how = (f"shifted {d.amplitude * 100:.0f} cm along {np.round(d.direction, 2)}, clearance {d.clearance * 100:.1f} cm"
               if d.direction is not None else "no shift found, left as planned")
        print(f"detour {d.limb} {d.t_start:.2f}-{d.t_end:.2f} s, {-d.depth * 100:.1f} cm in: {how}")
    steps = max(1, int(round(0.02 / sim.timestep)))
    next_t = args.start
    while not ex.done and ex.time <= args.stop:
        sim.step(steps)
        if ex.time >= next_t:
            next_t += args.every
            print(trace_line(ex, movable, cop=args.cop, grip=args.grip, contacts=args.contacts, joints=joints,
                             guard=args.guard), flush=True)
    print(f"fell: {ex.fell} at t={ex.time:.2f} s" if ex.fell else f"no fall up to t={ex.time:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
