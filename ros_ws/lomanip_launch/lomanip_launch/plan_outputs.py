"""Save a plan result under a run folder: summary, contacts, keyframes, trajectory arrays, plots.

Everything is written from the public messages (lomanip_msgs), so the same functions serve a plan
result received by `lomanip plan` and one read back from a bag. Files:

  summary.yaml      prompts, error code, message, stage timings, solver statistics, execution metrics
  contacts.yaml     contacts per subtask (limb, object, point, normal, confidence)
  keyframes.yaml    one 35-D configuration per subtask (base pose + 29 named joints)
  trajectory.npz    dense arrays on the trajectory's time grid (see ``trajectory_arrays``)
  trajectory.png    base, CoM, joints, contact normal forces and centroidal momentum over time
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from lomanip_msgs.msg import ErrorCode

LIMBS = ("left_foot", "right_foot", "left_hand", "right_hand")


def error_name(code: int) -> str:
    names = {getattr(ErrorCode, n): n for n in dir(ErrorCode) if n.isupper() and isinstance(getattr(ErrorCode, n), int)}
    return names.get(code, str(code))


def trajectory_arrays(traj) -> dict[str, np.ndarray]:
    """A WholeBodyTrajectory message as numpy arrays on its time grid (N points)."""
    pts = traj.joint_trajectory.points
    t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in pts])
    out: dict[str, np.ndarray] = {"t": t, "joint_names": np.array(traj.joint_trajectory.joint_names),
                                  "q": np.array([p.positions for p in pts]), "qd": np.array([p.velocities for p in pts])}
    base = [p.transforms[0] for p in traj.base_trajectory.points]
    out["base_position"] = np.array([[b.translation.x, b.translation.y, b.translation.z] for b in base])
    out["base_quaternion_xyzw"] = np.array([[b.rotation.x, b.rotation.y, b.rotation.z, b.rotation.w] for b in base])
    out["com"] = np.array([[c.x, c.y, c.z] for c in traj.com_position])
    out["linear_momentum"] = np.array([[v.x, v.y, v.z] for v in traj.linear_momentum])
    out["angular_momentum"] = np.array([[v.x, v.y, v.z] for v in traj.angular_momentum])
    wrench = np.zeros((len(traj.contact_wrenches), len(LIMBS), 6))
    for i, knot in enumerate(traj.contact_wrenches):
        for w in knot.wrenches:
            if w.limb in LIMBS:
                f, m = w.wrench.force, w.wrench.torque
                wrench[i, LIMBS.index(w.limb)] += [f.x, f.y, f.z, m.x, m.y, m.z]
    out["contact_wrench"] = wrench
    for obj in traj.object_trajectories:
        out[f"object_{obj.object_id}_position"] = np.array([[p.position.x, p.position.y, p.position.z] for p in obj.poses])
    return out


def _contacts(contact_set) -> list[dict]:
    return [{"subtask": s.subtask_index, "prompt": s.prompt,
             "contacts": [{"limb": c.limb, "object": c.object_id,
                           "position": [round(c.position.x, 4), round(c.position.y, 4), round(c.position.z, 4)],
                           "normal": [round(c.normal.x, 3), round(c.normal.y, 3), round(c.normal.z, 3)],
                           "confidence": round(c.confidence, 3)} for c in s.contacts]}
            for s in contact_set.subtasks]


def _keyframes(array) -> list[dict]:
    out = []
    for k in array.keyframes:
        p, o = k.base_pose.position, k.base_pose.orientation
        out.append({"subtask": k.subtask_index, "prompt": k.prompt,
                    "base_position": [round(p.x, 4), round(p.y, 4), round(p.z, 4)],
                    "base_quaternion_xyzw": [round(o.x, 4), round(o.y, 4), round(o.z, 4), round(o.w, 4)],
                    "joints": {n: round(float(q), 4) for n, q in zip(k.joints.name, k.joints.position)},
                    "contacts": [f"{c.limb}->{c.object_id}" for c in k.contacts]})
    return out


def summary(prompts: list[str], result, seconds: float) -> dict:
    stats = result.trajectory.solver_statistics
    ex = result.execution
    return {"prompts": list(prompts), "error_code": error_name(result.error_code.val),
            "message": result.error_code.message, "wall_time_s": round(seconds, 2),
            "stage_timings_s": {t.stage: round(t.seconds, 2) for t in result.timings},
            "solver": {"solver": stats.solver, "converged": stats.converged, "iterations": stats.iterations,
                       "build_time_s": round(stats.build_time, 2), "solve_time_s": round(stats.solve_time, 2),
                       "max_dynamics_violation": float(stats.max_dynamics_violation),
                       "max_contact_violation": float(stats.max_contact_violation),
                       "max_penetration_m": float(stats.max_penetration), "peak_memory_mb": round(stats.peak_memory_mb),
                       "status": stats.status_message},
            # only when the plan was executed (an empty ExecutionMetrics would read as a failed run); a
            # run that fell ends with EXECUTION_FAILED before its stage timing, but with its metrics
            "execution": {"task_success": ex.task_success, "detail": ex.task_success_detail, "fell": ex.fell,
                          "duration_s": round(ex.duration, 2), "real_time_factor": round(ex.real_time_factor, 2),
                          "max_base_position_error_m": round(ex.max_base_position_error, 4),
                          "max_joint_error_rad": round(ex.max_joint_error, 4)}
            if executed(result) else "not executed (add --execute)"}


def executed(result) -> bool:
    """Whether the plan ran under physics: an execution stage finished, or metrics came back."""
    return any(t.stage == "execution" for t in result.timings) or result.execution.duration > 0.0


def save_plan(run_dir: Path, prompts: list[str], result, seconds: float) -> list[Path]:
    """Write the files listed in the module docstring; returns their paths."""
    run_dir.mkdir(parents=True, exist_ok=True)
    written = []

    def dump(name: str, data) -> None:
        path = run_dir / name
        path.write_text(yaml.safe_dump(data, sort_keys=False, width=110), encoding="utf-8")
        written.append(path)

    dump("summary.yaml", summary(prompts, result, seconds))
    if result.contacts.subtasks:
        dump("contacts.yaml", _contacts(result.contacts))
    if result.keyframes.keyframes:
        dump("keyframes.yaml", _keyframes(result.keyframes))
    if result.trajectory.joint_trajectory.points:
        arrays = trajectory_arrays(result.trajectory)
        np.savez_compressed(run_dir / "trajectory.npz", **arrays)
        written.append(run_dir / "trajectory.npz")
        written.append(plot_trajectory(arrays, run_dir / "trajectory.png", prompts))
    return written


def plot_trajectory(a: dict[str, np.ndarray], path: Path, prompts: list[str]) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = a["t"]
    fig, axes = plt.subplots(5, 1, figsize=(9, 12), sharex=True)
    for i, axis in enumerate("xyz"):
        axes[0].plot(t, a["base_position"][:, i], label=f"pelvis {axis}")
    if len(a["com"]):
        axes[0].plot(t, a["com"][:, 2], "k--", label="CoM z")
    for key in (k for k in a if k.startswith("object_") and k.endswith("_position")):
        axes[0].plot(t, a[key][:, 2], ":", label=f"{key[7:-9]} z")
    axes[0].set_ylabel("m")
    axes[0].legend(fontsize=7, ncol=3)
    axes[1].plot(t, a["q"], lw=0.8)
    axes[1].set_ylabel("joint angles [rad]")
    axes[2].plot(t, a["qd"], lw=0.8)
    axes[2].set_ylabel("joint velocities [rad/s]")
    for j, limb in enumerate(LIMBS):
        if len(a["contact_wrench"]):
            axes[3].plot(t, a["contact_wrench"][:, j, 2], label=limb)
    axes[3].set_ylabel("contact force z [N]")
    axes[3].legend(fontsize=7, ncol=4)
    if len(a["linear_momentum"]):
        for i, axis in enumerate("xyz"):
            axes[4].plot(t, a["linear_momentum"][:, i], label=f"linear {axis} [kg m/s]")
            axes[4].plot(t, a["angular_momentum"][:, i], "--", label=f"angular {axis} [kg m²/s]")
    axes[4].set_ylabel("centroidal momentum")
    axes[4].legend(fontsize=7, ncol=3)
    axes[4].set_xlabel("time [s]")
    fig.suptitle(" → ".join(prompts), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
