"""Load hand-written TO problems (keyframes + contact schedule + scene) from YAML.

Schema (see ``config/s1_basket.yaml``): ``parameters`` (defaults, overridable: e.g. box_mass,
box_yaw), ``objects``, ``initial`` (base pose + joints), ``keyframes``, ``phases``,
``placement_goals``, ``options``.  Values may be strings with ``${name}`` references to parameters
(evaluated as Python arithmetic on the parameters, e.g. ``"${box_mass}"``).

Frames: a pose or point may be given in an object's INITIAL frame with ``frame: <object id>``
(keyframes, contacts, desired foot xy), so a demonstration written for a box at yaw 0 follows the
box when its initial yaw is a grid parameter.  Joints are written as overrides of the MJCF ``stand``
posture (``joints: {left_knee_joint: 0.6, ...}``), by name.
"""

from __future__ import annotations

import copy
import math
import os
import re

import numpy as np
import yaml

from .model import G1Model, rot_to_quat_xyzw, rpy_to_rot
from .problem import (TUPLE_OPTIONS, ContactPhase, ContactSpec, Keyframe, ObjectMotion, Options, PlacementGoal,
                      Primitive, Problem, SceneObject, option_item)

CONFIG_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "config"))


def config_path(name: str) -> str:
    p = name if os.path.isabs(name) else os.path.join(CONFIG_DIR, name)
    if not p.endswith(".yaml"):
        p += ".yaml"
    return p


def _subst(v, params):
    if isinstance(v, str) and "${" in v:
        expr = re.sub(r"\$\{(\w+)\}", lambda m: repr(params[m.group(1)]), v)
        return eval(expr, {"__builtins__": {}}, {"pi": math.pi, "cos": math.cos, "sin": math.sin, "round": round})
    if isinstance(v, list):
        return [_subst(x, params) for x in v]
    if isinstance(v, dict):
        return {k: _subst(x, params) for k, x in v.items()}
    return v


def load_options(d: dict | None, base: Options | None = None) -> Options:
    opt = copy.deepcopy(base) if base is not None else Options()
    for k, v in (d or {}).items():
        k, v = option_item(k, v)  # solver_options: a task file's name for ipopt (TrajectoryOptions.solver_options)
        if k == "ipopt":
            v = {**opt.ipopt, **v}
        if not hasattr(opt, k):
            raise ValueError(f"unknown TO option {k!r}")
        if k in TUPLE_OPTIONS:
            v = tuple(v)
        if k == "weights":
            w = dict(opt.weights)
            w.update(v)
            v = w
        setattr(opt, k, v)
    return opt


def _scenario_params(raw: dict, overrides: dict) -> tuple[dict, dict]:
    """(all substitution parameters, overrides meant for lomanip_sim) of a fixture."""
    local = dict(raw.get("parameters") or {})
    sim_over = {}
    for k, v in (overrides or {}).items():
        if k in local:
            local[k] = v
        elif raw.get("scenario"):
            sim_over[k] = v
        else:
            raise ValueError(f"unknown fixture parameter {k!r} (known: {sorted(local)})")
    return local, sim_over


def load_problem(name: str, overrides: dict | None = None, options: dict | None = None,
                 model: G1Model | None = None) -> Problem:
    """Load a fixture by name (``s1_basket``) or path; ``overrides`` replace its parameters.

    A fixture with ``scenario: <lomanip_sim scenario>`` takes its objects and their frames from the
    simulated world (:func:`lomanip_to.scene.scenario_scene`); overrides that are not fixture
    parameters (``box_mass``, ``box_yaw``, any scenarios.yaml key) go to the scenario.
    """
    with open(config_path(name)) as f:
        raw = yaml.safe_load(f)
    params, sim_over = _scenario_params(raw, overrides or {})
    sc_objects, sc_frames = None, {}
    if raw.get("scenario"):
        from .scene import scenario_scene

        sc_params, sc_objects, sc_frames = scenario_scene(raw["scenario"], sim_over)
        params = {**sc_params.to_dict(), **params}
    raw = _subst({k: v for k, v in raw.items() if k != "parameters"}, params)
    model = model or G1Model()
    solver_defaults = {}
    so = os.path.join(CONFIG_DIR, "solver.yaml")
    if os.path.isfile(so):
        with open(so) as f:
            solver_defaults = yaml.safe_load(f) or {}
    opt = load_options(solver_defaults.get("options"), None)
    opt = load_options(raw.get("options"), opt)
    opt = load_options(options, opt)

    objects = list(sc_objects or [])
    frames = {k: (fr.origin, fr.R, fr.yaw) for k, fr in sc_frames.items()}
    for o in raw.get("objects", []):
        rpy = [0.0, 0.0, float(o.get("yaw", 0.0))]
        R = rpy_to_rot(np.array(rpy))
        prims = [Primitive(p["kind"], tuple(p["size"]), tuple(p.get("position", (0, 0, 0))), float(p.get("yaw", 0.0)))
                 for p in o["primitives"]]
        so_ = SceneObject(id=o["id"], object_class=o.get("class", o["id"]), movable=bool(o.get("movable", False)),
                          position=tuple(float(v) for v in o["position"]), quat_xyzw=tuple(rot_to_quat_xyzw(R)),
                          mass=float(o.get("mass", 0.0)), primitives=prims,
                          rear_axle=tuple(o.get("rear_axle", (0.0, 0.0, 0.0))))
        if "inertia" in o:
            so_.inertia = tuple(o["inertia"])
        objects.append(so_)
        frames[o["id"]] = (np.asarray(so_.position, float), R, rpy[2])

    # derived frames: {name: {position: [...], yaw: expr}} (e.g. a grasp frame of a square box)
    # ``frame`` = parent frame; ``snap_yaw: P`` keeps only the parent yaw modulo P in [-P/2, P/2)
    # (the grasp frame of a square box: the pair of faces closest to the robot's lateral axis)
    for name, fd in (raw.get("frames") or {}).items():
        c0, R0, yaw0 = frames[fd["frame"]] if fd.get("frame") else (np.zeros(3), np.eye(3), 0.0)
        if fd.get("snap_yaw"):
            per = float(fd["snap_yaw"])
            yaw0 = yaw0 - per * math.floor(yaw0 / per + 0.5)
            R0 = rpy_to_rot(np.array([0.0, 0.0, yaw0]))
        yaw = yaw0 + float(fd.get("yaw", 0.0))
        frames[name] = (c0 + R0 @ np.asarray(fd.get("position", (0, 0, 0)), float),
                        rpy_to_rot(np.array([0.0, 0.0, yaw])), yaw)

    def to_world_point(p, frame):
        if p is None:
            return None
        p = np.asarray(p, float)
        if not frame:
            return tuple(p)
        c, R, _ = frames[frame]
        return tuple(c + R @ p)

    def to_world_dir(n, frame):
        n = np.asarray(n, float)
        if not frame:
            return tuple(n)
        return tuple(frames[frame][1] @ n)

    def joints_of(spec):
        th = model.theta_stand.copy()
        for k, v in (spec or {}).items():
            if k not in model.joint_names:
                raise ValueError(f"unknown joint {k!r}")
            th[model.joint_names.index(k)] = float(v)
        return th

    def base_of(d):
        frame = d.get("frame", "")
        p = np.asarray(d["base_position"], float)
        yaw = float(d.get("base_rpy", [0, 0, 0])[2])
        rpy = np.asarray(d.get("base_rpy", [0, 0, 0]), float)
        if frame:
            c, R, oyaw = frames[frame]
            p = c + R @ p
            rpy = np.array([rpy[0], rpy[1], yaw + oyaw])
        if d.get("base_height") is not None:
            p[2] = float(d["base_height"])
        return p, rpy

    def contact_of(limb, c):
        if isinstance(c, str):
            return ContactSpec(limb, c, None, (0, 0, 1))
        frame = c.get("frame", "")
        return ContactSpec(limb, c.get("object", "floor"), to_world_point(c.get("position"), frame),
                           to_world_dir(c.get("normal", (0, 0, 1)), frame))

    ini = raw["initial"]
    p0, rpy0 = base_of(ini)
    x0 = np.concatenate([p0, rpy0, joints_of(ini.get("joints"))])
    if ini.get("base_height") is None and ini.get("auto_height", True):
        x0[2] = model.x_stand()[2]

    keyframes = []
    for kd in raw.get("keyframes", []):
        p, rpy = base_of(kd)
        th = joints_of(kd.get("joints"))
        contacts = [contact_of(l, c) for l, c in (kd.get("contacts") or {}).items()]
        fd = kd.get("desired_foot_xy")
        if fd is not None:
            fd = tuple(np.asarray(to_world_point([fd[0], fd[1], 0.0], kd.get("foot_frame", kd.get("frame", ""))))[:2])
        if kd.get("ik", False):  # complete the hand-written keyframe (ik.py): contacts met exactly
            from .ik import SOLE_FORWARD, complete_keyframe

            hands = {c.limb: c.position for c in contacts if c.limb in ("left_hand", "right_hand")}
            h = float(kd.get("foot_height", 0.0))
            if fd is None:  # mid-foot of the nominal stance under the written base pose
                fd = tuple(p[:2] + SOLE_FORWARD * np.array([np.cos(rpy[2]), np.sin(rpy[2])]))
            xk = complete_keyframe(model, np.concatenate([p, rpy, th]), (h, h), hands)
            p, rpy, th = xk[:3], xk[3:6], xk[6:]
        keyframes.append(Keyframe(subtask_index=int(kd["subtask"]), base_position=tuple(p),
                                  base_quat_xyzw=tuple(rot_to_quat_xyzw(rpy_to_rot(rpy))), joints=tuple(th),
                                  contacts=contacts, desired_foot_xy=fd,
                                  reference_object_id=kd.get("reference_object", ""), prompt=kd.get("prompt", ""),
                                  time=kd.get("time")))
    phases = []
    for pd in raw["phases"]:
        contacts = {l: contact_of(l, c) for l, c in (pd.get("contacts") or {}).items()}
        objs = {}
        for oid, od in (pd.get("objects") or {}).items():
            if isinstance(od, str):
                od = {"mode": od}
            objs[oid] = ObjectMotion(mode=od.get("mode", "free"), support=od.get("support", "floor"),
                                     attached_to=od.get("attached_to", ""))
        phases.append(ContactPhase(start=float(pd["start"]), end=float(pd["end"]),
                                   phase_type=pd.get("type", "stance"), subtask_index=int(pd.get("subtask", 0)),
                                   contacts=contacts, objects=objs))
    goals = []
    for g in raw.get("placement_goals", []) or []:
        frame = g.get("frame", "")
        pos = to_world_point(g["position"], frame)
        yaw = float(g.get("yaw", 0.0)) + (frames[frame][2] if frame and g.get("yaw_in_frame", False) else 0.0)
        goals.append(PlacementGoal(object_id=g["object"], position=pos, yaw=yaw, time=g.get("time"),
                                   weight=float(g.get("weight", 1e3))))
    return Problem(objects=objects, keyframes=keyframes, phases=phases, initial_configuration=tuple(x0),
                   placement_goals=goals, options=opt, name=raw.get("name", os.path.basename(name)))
