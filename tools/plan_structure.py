#!/usr/bin/env python3
"""Structure of a plan: horizon, phases, steps per subtask, keyframe pelvis heights, step lengths.

Why: the TO converges on the hand-written S1 fixture (18.2 s, 2 steps to the box, 8 carrying it,
the basket lifted at the end) but stalls on S1 generated from prompts (36 s, 77 phases). This
prints both side by side in the same terms so changes to perception's synthetic demonstration and
the planner's schedule can be measured against the fixture.

    .venv/bin/python tools/plan_structure.py                       # S1 fixture vs S1 from prompts
    .venv/bin/python tools/plan_structure.py --task s2_trolley --set box_yaw=0.6
    .venv/bin/python tools/plan_structure.py --grid                # every grid point of S1 and S2
    nice -n 5 .venv/bin/python tools/plan_structure.py --solve 1200  # + one TO solve (minutes)
    .venv/bin/python tools/plan_structure.py --task s2_trolley --no-fixture --solve 3000 --subtasks 2 \
        --option waist_yaw_range=0.5 --out runs/s2_pick_carry      # then: tools/exec_trace.py runs/s2_pick_carry/s2_trolley.npz
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
WALKING = "walking"


@dataclass
class SubtaskStructure:
    """What one subtask of a plan looks like (for comparison with the fixture)."""

    index: int
    start: float
    end: float
    steps: int                      # walking phases (one foot swings each)
    carrying_steps: int             # walking phases with an object free (carried)
    keyframe_time: float | None
    pelvis_z: float                 # keyframe base height (m)
    approach_deg: float | None      # keyframe pelvis heading relative to the hand object's yaw
    pelvis_in_object: tuple | None  # keyframe pelvis xy in the hand object's frame (m), the object
                                    # where the plan has it then (its placement goal once placed)
    step_lengths: list = field(default_factory=list)  # per walking phase: swing foot displacement (m)


@dataclass
class PlanStructure:
    name: str
    horizon: float
    phases: int
    subtasks: list


def _yaw_of_quat_xyzw(q) -> float:
    x, y, z, w = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def structure(problem, name: str = "") -> PlanStructure:
    """Measure a lomanip_to Problem (fixture or generated)."""
    objects = {o.id: o for o in problem.objects}
    subs = sorted({ph.subtask_index for ph in problem.phases})
    out = []
    for s in subs:
        phs = [ph for ph in problem.phases if ph.subtask_index == s]
        walk = [ph for ph in phs if ph.phase_type == WALKING]
        carrying = [ph for ph in walk if any(m.mode == "free" for m in ph.objects.values())]
        lengths = []
        # swing foot displacement: foot position in the phase after the swing vs before it
        idx = [problem.phases.index(ph) for ph in walk]
        for i in idx:
            if i == 0 or i + 1 >= len(problem.phases):
                continue
            before, after = problem.phases[i - 1].contacts, problem.phases[i + 1].contacts
            swing = [f for f in ("left_foot", "right_foot") if f not in problem.phases[i].contacts]
            for f in swing:
                a, b = before.get(f), after.get(f)
                if a is not None and b is not None and a.position is not None and b.position is not None \
                        and len(a.position) and len(b.position):
                    lengths.append(float(np.linalg.norm(np.subtract(b.position, a.position)[:2])))
        kf = next((k for k in problem.keyframes if k.subtask_index == s), None)
        approach = pelvis_local = None
        pelvis_z = float("nan")
        kt = None
        if kf is not None:
            kt = problem.keyframe_time(kf)
            pelvis_z = float(kf.base_position[2])
            oid = kf.reference_object_id or next((c.object_id for c in kf.contacts), "")
            if oid in objects:
                o = objects[oid]
                opos, oyaw = o.position, o.yaw()
                for g in problem.placement_goals:   # where the plan has the object at the keyframe
                    if g.object_id == oid and (g.time is None or g.time <= kt + 1e-6):
                        opos, oyaw = g.position, g.yaw
                c, sn = math.cos(oyaw), math.sin(oyaw)
                d = np.subtract(kf.base_position[:2], opos[:2])
                pelvis_local = (float(c * d[0] + sn * d[1]), float(-sn * d[0] + c * d[1]))
                approach = math.degrees(math.remainder(_yaw_of_quat_xyzw(kf.base_quat_xyzw) - oyaw, 2 * math.pi))
        out.append(SubtaskStructure(s, phs[0].start, phs[-1].end, len(walk), len(carrying), kt, pelvis_z,
                                    approach, pelvis_local, lengths))
    return PlanStructure(name, problem.duration, len(problem.phases), out)


def fixture_problem(name: str, overrides: dict):
    from lomanip_to.fixtures import load_problem

    return load_problem(name, overrides)


def generated_problem(task_name: str, overrides: dict | None = None):
    """The planner's problem for a task file (no TO solve); returns (problem, OfflinePlan)."""
    from lomanip_planner import offline
    from lomanip_to.problem import PlacementGoal

    task = load_task(task_name)
    ov = {**(task.get("scenario_overrides") or {}), **(overrides or {})}
    goals = {g["object"]: PlacementGoal(g["object"], tuple(g["position"]), float(g.get("yaw", 0.0)))
             for g in task.get("placement_goals", [])}
    plan = offline.plan(task["scenario"], task["prompts"], goals, ov, solve=False)
    return plan.problem, plan


def first_subtasks(problem, n: int):
    """``problem`` cut after its first ``n`` subtasks: their phases, keyframes and the placement goals
    timed inside them. Why: S2's pick and carry solve in minutes where its push does not, so they
    can be solved and executed on their own (docs/execution.md, sessions 34-35)."""
    from dataclasses import replace

    phases = [ph for ph in problem.phases if ph.subtask_index < n]
    if not phases:
        raise ValueError(f"--subtasks {n}: the problem has no subtask below {n}")
    end = max(ph.end for ph in phases)
    return replace(problem, phases=phases, keyframes=[k for k in problem.keyframes if k.subtask_index < n],
                   placement_goals=[g for g in problem.placement_goals if g.time is not None and g.time <= end + 1e-9])


def load_task(task_name: str) -> dict:
    """A task file of ros_ws/config/tasks as YAML."""
    return yaml.safe_load((ROOT / "ros_ws/config/tasks" / f"{task_name}.yaml").read_text())


def solver_options(time_limit: float, requested: dict | None = None):
    """The TO options of a plan request: lomanip_to/config/solver.yaml's defaults with the task
    file's ``options`` on top (as the planner's request carries them), and this time limit.

    Why: without them ``--solve`` solved S1 and S2 from prompts without e.g. S2's ``carry_reach``
    or S1's ``dt_lift`` (docs/to.md, session 32)."""
    from lomanip_to.fixtures import CONFIG_DIR, load_options

    defaults = yaml.safe_load((Path(CONFIG_DIR) / "solver.yaml").read_text()) or {}
    base = load_options(defaults.get("options"), None)
    return load_options(requested, base).replaced(time_limit=float(time_limit))


def solve(problem, time_limit: float, out: Path | None = None, requested: dict | None = None,
          case: dict | None = None) -> None:
    """One TO solve of a generated problem, printing progress every 10 iterations and per stage.
    With ``out`` it saves the result there and, beside it, the problem (``<stem>.problem.pkl``) and
    ``case`` (``<stem>.case.yaml``: task, scenario overrides), which ``tools/exec_trace.py`` reads to
    execute the plan in its task's world."""
    import time as _time
    from dataclasses import replace

    from lomanip_to import solver

    prob = replace(problem, options=solver_options(time_limit, requested))
    print(f"TO options: the task file's {sorted(requested or {})} over solver.yaml, time limit {time_limit:.0f} s",
          flush=True)
    last = {"stage": None}

    def progress(p) -> None:
        if p.stage != last["stage"] or p.iteration % 10 == 0:
            print(f"    {p.text()}", flush=True)
            last["stage"] = p.stage

    t0 = _time.perf_counter()
    res = solver.solve(prob, progress=progress)
    st = res.stats
    print(f"TO: {st.status_message()}; success {res.success}; build {st.build_time:.1f} s, solve "
          f"{st.solve_time:.1f} s (wall {_time.perf_counter() - t0:.0f} s), peak {st.peak_memory_mb:.0f} MB, "
          f"{st.n_knots} knots", flush=True)
    for stage in st.stages:
        print(f"  {stage['stage']}: {stage['status']}, {stage['iterations']} it, {stage['time']:.1f} s, "
              f"{stage.get('regularised_iterations', 0)} regularised", flush=True)
    if out is not None:
        import pickle

        out.parent.mkdir(parents=True, exist_ok=True)
        res.save(out)
        with open(out.with_suffix(".problem.pkl"), "wb") as f:
            pickle.dump(problem, f)
        out.with_suffix(".case.yaml").write_text(yaml.safe_dump(dict(case or {}), sort_keys=False))
        print(f"  saved {out} (+ .problem.pkl, .case.yaml)")


def format_structure(ps: PlanStructure) -> str:
    lines = [f"{ps.name}: horizon {ps.horizon:.1f} s, {ps.phases} phases"]
    for s in ps.subtasks:
        sl = s.step_lengths
        steps = f"{s.steps} steps ({s.carrying_steps} carrying)"
        lens = f", step length mean {np.mean(sl):.2f} max {max(sl):.2f} m" if sl else ""
        app = (f", heading vs object {s.approach_deg:+.0f} deg, pelvis in object frame "
               f"({s.pelvis_in_object[0]:+.2f}, {s.pelvis_in_object[1]:+.2f})") if s.approach_deg is not None else ""
        kt = f"{s.keyframe_time:.1f}" if s.keyframe_time is not None else "-"
        lines.append(f"  subtask {s.index}: {s.start:.1f}-{s.end:.1f} s, {steps}{lens}; keyframe at {kt} s, "
                     f"pelvis z {s.pelvis_z:.2f} m{app}")
    return "\n".join(lines)


def _parse_set(items: list[str]) -> dict:
    out = {}
    for it in items:
        k, v = it.split("=", 1)
        out[k] = yaml.safe_load(v)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="s1_basket")
    ap.add_argument("--set", nargs="*", default=[], help="scenario overrides KEY=VALUE")
    ap.add_argument("--no-fixture", action="store_true")
    ap.add_argument("--grid", action="store_true", help="S1 and S2 over their box_yaw grids (box_mass 2.5)")
    ap.add_argument("--solve", type=float, default=0.0, metavar="SECONDS",
                    help="also solve the generated problem with the TO under this time limit (one solve)")
    ap.add_argument("--subtasks", type=int, default=0, metavar="N",
                    help="solve only the first N subtasks of the generated problem (0 = all)")
    ap.add_argument("--option", nargs="*", default=[], metavar="KEY=YAML",
                    help="TO options over the task file's, e.g. waist_yaw_range=0.5")
    ap.add_argument("--out", type=Path, default=ROOT / "runs/plan_structure")
    args = ap.parse_args()
    ov = _parse_set(args.set)
    try:
        extra = _parse_set(args.option)
    except ValueError:
        print("plan_structure: --option takes KEY=YAML items", file=sys.stderr)
        return 2
    if args.grid:
        for task, yaws in (("s1_basket", (0.0, 0.6, 1.2)), ("s2_trolley", (0.0, 0.6, -0.6, 1.2, -1.2))):
            for y in yaws:
                prob, _ = generated_problem(task, {"box_yaw": y})
                print(format_structure(structure(prob, f"{task} box_yaw={y} from prompts")), flush=True)
        return 0
    if not args.no_fixture:
        try:
            print(format_structure(structure(fixture_problem(args.task, ov), f"{args.task} fixture")), flush=True)
        except Exception as exc:  # noqa: BLE001 - a task without a fixture
            print(f"{args.task} fixture: {type(exc).__name__}: {exc}")
    prob, _ = generated_problem(args.task, ov)
    print(format_structure(structure(prob, f"{args.task} from prompts")), flush=True)
    if args.solve > 0:
        if args.subtasks > 0:
            try:
                prob = first_subtasks(prob, args.subtasks)
            except ValueError as exc:
                print(f"plan_structure: {exc}", file=sys.stderr)
                return 2
            print(f"solving the first {args.subtasks} subtask(s): horizon {prob.duration:.1f} s", flush=True)
        tag = "_".join(f"{k}{v}" for k, v in sorted(ov.items()))
        options = {**(load_task(args.task).get("options") or {}), **extra}
        solve(prob, args.solve, args.out / f"{args.task}{'_' + tag if tag else ''}.npz", options,
              {"task": args.task, "scenario_overrides": ov})
    return 0


if __name__ == "__main__":
    sys.exit(main())
