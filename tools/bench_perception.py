#!/usr/bin/env python3
"""Contact-transfer benchmark on synthetic demonstrations (issue 4; paper Sec. III-A2 and V-B).

For each object class of S1/S2 (box, basket, shelf, table, trolley) it generates N synthetic
demonstrations (a person doing a subtask on another instance of the class, random viewpoint,
1024 x 1024, camera unknown to the pipeline) and transfers their contacts onto the simulated
scene's object, for every corruption setting of the stand-ins:

  * matcher outlier rate (incl. left/right flips) 0, 20, 40, 60 % at 10 % depth scale error;
  * depth scale error 0, 10, 20 % at 40 % outliers (``--grid full``: the whole 4 x 3 grid);

with the geometry-aware transfer (similarity SVD, the default; rigid SVD, as in the paper, on the
40 %-outlier settings) and the geometry-unaware ablation.
Error of a contact = distance to the ground truth (the demo's true contact, in the demo object's
canonical coordinates, placed on the scene object), after projection to the object surface.

Prints the sweep table (median and p90 in cm, per method) and the per-class table at the
acceptance point; writes results.json, per-contact errors (errors.csv), a plot of error vs outlier
rate and sample images (R_g with the pose's contact keypoints | R_s with the transferred and true
contacts) under runs/bench_perception/<timestamp>/. Runtime figures are per subtask on this
machine (2 shared cores: expect them higher than on an idle machine).

  .venv/bin/python tools/bench_perception.py                # 50 demos per class (about 20-30 min)
  .venv/bin/python tools/bench_perception.py --demos 5      # quick look
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import replace
from datetime import datetime
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
for pkg in ("src/lomanip_sim", "src/lomanip_perception"):
    sys.path.insert(0, str(ROOT / pkg))

import cv2  # noqa: E402

from lomanip_perception.config import build_from_config, load_config  # noqa: E402
from lomanip_perception.evaluation import contact_errors, sim_scene  # noqa: E402
from lomanip_perception.pipeline import PerceptionPipeline  # noqa: E402
from lomanip_perception.prompts import parse_subtask  # noqa: E402
from lomanip_perception.registry import build_models  # noqa: E402

#: class -> [(scenario, prompt)]; a demo of class C is scored on its contacts with the C object
CLASS_TASKS = {
    "box": [("s1_basket", "pick up the box"), ("s1_basket", "place the box next to the shelf"),
            ("s1_basket", "step on the box"), ("s2_trolley", "pick up the box from the table"),
            ("s2_trolley", "place the box on the trolley")],
    "basket": [("s1_basket", "step on the box and grab the basket"), ("s1_basket", "grab the basket")],
    "shelf": [("s1_basket", "push the shelf")],
    "table": [("s2_trolley", "push the table")],
    "trolley": [("s2_trolley", "push the trolley forward"), ("s2_trolley", "push the trolley")],
}
SCENE_YAWS = {"s1_basket": [0.0, 0.6, 1.2], "s2_trolley": [0.0, 0.6, -1.2]}
OUTLIERS = [0.0, 0.2, 0.4, 0.6]
DEPTH_ERRORS = [0.0, 0.1, 0.2]
ACCEPT = (0.4, 0.1)
METHODS = ("aware_similarity", "aware_rigid", "unaware")


def settings(grid: str) -> list[tuple[float, float]]:
    if grid == "full":
        return [(o, d) for d in DEPTH_ERRORS for o in OUTLIERS]
    cross = [(o, ACCEPT[1]) for o in OUTLIERS] + [(ACCEPT[0], d) for d in DEPTH_ERRORS if d != ACCEPT[1]]
    return cross


def pipelines(cfg: dict, outlier: float, depth_err: float, methods) -> dict[str, PerceptionPipeline]:
    base_models = dict(cfg["models"])
    base_models["matcher"] = {"backend": "synthetic", "params": {**cfg["models"]["matcher"]["params"],
                                                                 "outlier_rate": outlier}}  # fmt: skip
    base_models["depth_estimator"] = {"backend": "synthetic", "params": {**cfg["models"]["depth_estimator"]["params"],
                                                                         "scale_error": depth_err}}  # fmt: skip
    models = build_models(base_models)
    _, tcfg, seed = build_from_config(cfg)
    out = {}
    for m in methods:
        t = replace(tcfg, method="geometry_unaware" if m == "unaware" else "geometry_aware",
                    similarity=(m != "aware_rigid"))  # fmt: skip
        out[m] = PerceptionPipeline(models, t, seed)
    return out


MIRROR = {"left_hand": "right_hand", "right_hand": "left_hand", "left_foot": "right_foot", "right_foot": "left_foot"}


def is_flip(e, errs, min_separation: float = 0.10) -> bool:
    """A left/right flip: the contact landed nearer the mirror limb's true contact than its own (only
    where the two true contacts are at least ``min_separation`` apart on the same object)."""
    other = next((o for o in errs if o.limb == MIRROR.get(e.limb) and o.object_id == e.object_id), None)
    if other is None or np.linalg.norm(e.truth - other.truth) < min_separation:
        return False
    return bool(np.linalg.norm(e.predicted - other.truth) < np.linalg.norm(e.predicted - e.truth))


def stats(errs: list[float], flips: list[bool] | None = None) -> dict:
    a = np.asarray(errs, float)
    if a.size == 0:
        return {"n": 0, "median_cm": float("nan"), "p90_cm": float("nan"), "over6_pct": float("nan"),
                "over15_pct": float("nan"), "flip_pct": float("nan")}
    return {"n": int(a.size), "median_cm": float(np.median(a) * 100), "p90_cm": float(np.percentile(a, 90) * 100),
            "over6_pct": float((a > 0.06).mean() * 100), "over15_pct": float((a > 0.15).mean() * 100),
            "flip_pct": float(np.mean(flips) * 100) if flips else float("nan")}


SHORT = {"left_hand": "LH", "right_hand": "RH", "left_foot": "LF", "right_foot": "RF"}


def draw_sample(path: Path, demo, pose_uv: dict, scene, results: dict, truths: dict, caption: str = "") -> np.ndarray:
    """R_g with its true contacts (yellow, labelled) | R_s with transferred (geometry-aware: green,
    geometry-unaware: red) and true (white ring) contacts. Writes ``path``, returns the BGR image."""
    left = np.ascontiguousarray(demo.rgb[..., ::-1])
    for limb, uv in pose_uv.items():
        cv2.circle(left, (int(uv[0]), int(uv[1])), 14, (0, 255, 255), 4)
        cv2.putText(left, SHORT.get(limb, limb), (int(uv[0]) + 16, int(uv[1]) - 10), cv2.FONT_HERSHEY_SIMPLEX, 1.4,
                    (0, 255, 255), 3, cv2.LINE_AA)  # fmt: skip
    left = cv2.resize(left, (480, 480), interpolation=cv2.INTER_AREA)
    img = np.ascontiguousarray(scene.image.rgb[..., ::-1]).copy()
    cam, pose = scene.image.camera, scene.image.camera_pose
    def px(p):
        u, v = cam.project(pose.inverse_apply(p))[0]
        return int(round(u)), int(round(v))
    for p in truths.values():
        cv2.circle(img, px(p), 7, (255, 255, 255), 2)
    colours = {"aware_similarity": (0, 200, 0), "unaware": (0, 0, 230)}
    for m, pts in results.items():
        for p in pts.values():
            cv2.circle(img, px(p), 4, colours.get(m, (200, 200, 0)), -1)
    # crop R_s around the contacts (at least 240 px, 4:3) so they are readable beside R_g
    pts = np.array([px(p) for p in truths.values()] + [px(p) for pts in results.values() for p in pts.values()])
    H, W = img.shape[:2]
    c = pts.mean(0) if len(pts) else np.array([W / 2, H / 2])
    half = max(120, 0.5 * float(np.ptp(pts, 0).max()) + 70) if len(pts) else H / 2
    hw, hh = min(W / 2, half * 4 / 3), min(H / 2, half)
    x0, y0 = int(np.clip(c[0] - hw, 0, W - 2 * hw)), int(np.clip(c[1] - hh, 0, H - 2 * hh))
    img = img[y0:y0 + int(2 * hh), x0:x0 + int(2 * hw)]
    img = cv2.resize(img, (int(img.shape[1] * 480 / img.shape[0]), 480), interpolation=cv2.INTER_CUBIC)
    out = np.hstack([left, img])
    text = [(caption, (255, 255, 255)), ("generated demo R_g (synthetic) | scene R_s: green aware, red unaware, "
                                         "white ring truth", (220, 220, 220))]  # fmt: skip
    out = np.vstack([np.zeros((48, out.shape[1], 3), np.uint8), out])  # caption banner
    for k, (t, colour) in enumerate(text):
        cv2.putText(out, t, (8, 20 + 20 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.55, colour, 1, cv2.LINE_AA)
    cv2.imwrite(str(path), out)
    return out


def figure(path: Path, rows: list[np.ndarray], row_height: int = 300) -> None:
    """Stack sample images (one per class) into one PNG figure for the README (< 1 MB at 300 px rows)."""
    if not rows:
        return
    rs = [cv2.resize(r, (int(r.shape[1] * row_height / r.shape[0]), row_height), interpolation=cv2.INTER_AREA)
          for r in rows]  # fmt: skip
    w = max(r.shape[1] for r in rs)
    rs = [np.pad(r, ((0, 4), (0, w - r.shape[1]), (0, 0))) for r in rs]
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.vstack(rs), [cv2.IMWRITE_PNG_COMPRESSION, 9])


def measure_startup(config_file: str | None, timeout: float = 90.0) -> dict:
    """Start the perception node as a process (LOCALHOST discovery, own domain id): wall time from
    spawn to its 'ready' log line (offline default), or to its exit (a backend that cannot load),
    whether libtorch is mapped into the process, and its last log line."""
    import os
    import signal
    import subprocess
    import tempfile

    paths = [str(ROOT / p) for p in ("src/lomanip_sim", "src/lomanip_perception")]
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": str(150 + os.getpid() % 80),
           "PYTHONPATH": os.pathsep.join(paths + [os.environ.get("PYTHONPATH", "")]),
           "HF_HUB_CACHE": tempfile.mkdtemp(prefix="empty_hf_cache_")}  # "without weights", whatever this host has
    cmd = [sys.executable, "-m", "lomanip_perception.perception_node"]
    if config_file:
        cmd += ["--ros-args", "-p", f"config_file:={config_file}"]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)  # fmt: skip
    lines, ready, torch_loaded = [], None, None
    try:
        for line in proc.stdout:
            lines.append(line.rstrip())
            if "ready in" in line:
                ready = time.monotonic() - t0
                maps = Path(f"/proc/{proc.pid}/maps").read_text()
                torch_loaded = "libtorch" in maps
                break
            if time.monotonic() - t0 > timeout:
                break
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)
    end = time.monotonic() - t0
    import shutil

    shutil.rmtree(env["HF_HUB_CACHE"], ignore_errors=True)
    return {"config": config_file or "default (config/perception.yaml)", "ready_s": ready,
            "exit_s": None if ready else end, "returncode": proc.returncode if not ready else None,
            "libtorch_loaded": torch_loaded, "last_line": lines[-1] if lines else "",
            "role_lines": [ln.split("]: ", 1)[-1] for ln in lines if "]: role " in ln]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--demos", type=int, default=50, help="demonstrations per object class")
    ap.add_argument("--grid", choices=["cross", "full"], default="cross")
    ap.add_argument("--classes", default=",".join(CLASS_TASKS))
    ap.add_argument("--samples", type=int, default=2, help="sample images per class")
    ap.add_argument("--no-startup", action="store_true", help="skip the node start-up measurement")
    ap.add_argument("--docs-figure", default="", help="also write the contact-transfer figure here (e.g. "
                                                      "docs/img/contact_transfer.png)")
    ap.add_argument("--out", default=str(ROOT / "runs" / "bench_perception" / datetime.now().strftime("%Y%m%d-%H%M%S")))
    args = ap.parse_args()
    out = Path(args.out)
    (out / "samples").mkdir(parents=True, exist_ok=True)
    cfg = load_config()
    grid = settings(args.grid)
    classes = [c.strip() for c in args.classes.split(",") if c.strip()]
    print(f"bench_perception: {args.demos} synthetic demos x {len(classes)} classes, {len(grid)} corruption settings, "
          f"methods {', '.join(METHODS)} (synthetic stand-ins, not the paper's models); output {out}", flush=True)
    t0 = time.perf_counter()
    scenes = {(s, y): sim_scene(s, {"box_yaw": y}) for s, ys in SCENE_YAWS.items() for y in ys}
    print(f"  rendered {len(scenes)} scene frames in {time.perf_counter() - t0:.1f} s", flush=True)
    pipes = {g: pipelines(cfg, g[0], g[1], METHODS if g[0] == ACCEPT[0] else ("aware_similarity", "unaware")) for g in grid}
    gen_pipe = next(iter(pipes[grid[0]].values()))
    rows = []  # per contact
    runtime = []  # per subtask, aware similarity at the acceptance point
    failures = []
    startup = []
    if not args.no_startup:
        for cfg_file in (None, str(ROOT / "src/lomanip_perception/config/paper_models.yaml")):
            r = measure_startup(cfg_file)
            startup.append(r)
            print(f"  node start-up, {r['config']}: " + (f"ready after {r['ready_s']:.2f} s (spawn to 'ready' log), "
                  f"libtorch mapped: {r['libtorch_loaded']}" if r["ready_s"] else
                  f"exited {r['returncode']} after {r['exit_s']:.2f} s: {r['last_line']}"), flush=True)  # fmt: skip
            for ln in r["role_lines"]:
                print(f"    {ln}")
    fig_rows = []
    for cls in classes:
        n_samples = 0
        for i in range(args.demos):
            scen, prompt = CLASS_TASKS[cls][i % len(CLASS_TASKS[cls])]
            ys = SCENE_YAWS[scen]
            scene = scenes[(scen, ys[(i // len(CLASS_TASKS[cls])) % len(ys)])]
            st = parse_subtask(0, prompt, scene.classes())
            tg = time.perf_counter()
            demo = gen_pipe.generate(st, scene, seed=10_000 * (1 + list(CLASS_TASKS).index(cls)) + i)
            t_gen = time.perf_counter() - tg
            ids = {o.id for o in scene.objects if o.object_class == cls}
            for g in grid:
                sample_pts, truths = {}, {}
                for m, pipe in pipes[g].items():
                    try:
                        res = pipe.run_subtask(st, scene, demo=demo)
                    except Exception as exc:  # a failed transfer counts, it is not skipped silently
                        failures.append({"class": cls, "demo": i, "prompt": prompt, "setting": g, "method": m,
                                         "error": f"{type(exc).__name__}: {exc}"})  # fmt: skip
                        continue
                    if m == "aware_similarity" and g == ACCEPT:
                        runtime.append({**{f"{k}_s": v for k, v in res.timings.items() if k != "image_generation"},
                                        "transfer_s": res.timings["contact_transfer"],
                                        "perception_s": sum(v for k, v in res.timings.items() if k != "image_generation"),
                                        "generation_s": t_gen})  # fmt: skip
                    errs = [e for e in contact_errors(res, demo, scene) if e.object_id in ids]
                    for e in errs:
                        rows.append({"class": cls, "demo": i, "prompt": prompt, "outlier": g[0], "depth_err": g[1],
                                     "method": m, "limb": e.limb, "error_m": e.error, "error_raw_m": e.error_raw,
                                     "flip": is_flip(e, errs)})
                        if g == ACCEPT and m in ("aware_similarity", "unaware"):
                            sample_pts.setdefault(m, {})[e.limb] = e.predicted
                            truths[e.limb] = e.truth
                if g == ACCEPT and n_samples < args.samples and sample_pts:
                    gt = demo.ground_truth
                    uv = {c.limb: gt.camera.project(gt.camera_pose.inverse_apply(c.point))[0] for c in gt.contacts
                          if c.object_name in gt.names_of_class(cls)}  # fmt: skip
                    img = draw_sample(out / "samples" / f"{cls}_{i:02d}.png", demo, uv, scene, sample_pts, truths,
                                      f"{cls}: '{prompt}' ({scen}), {ACCEPT[0]:.0%} outliers, {ACCEPT[1]:.0%} depth scale")
                    if n_samples == 0:
                        fig_rows.append(img)
                    n_samples += 1
            if (i + 1) % 10 == 0:
                print(f"  {cls}: {i + 1}/{args.demos} demos ({time.perf_counter() - t0:.0f} s)", flush=True)

    def sel(**kw):
        return [r["error_m"] for r in rows if all(r[k] == v for k, v in kw.items())]

    def sel_flip(**kw):
        return [r["flip"] for r in rows if all(r[k] == v for k, v in kw.items())]

    table = []
    for g in grid:
        for m in pipes[g]:
            kw = {"outlier": g[0], "depth_err": g[1], "method": m}
            table.append({**kw, **stats(sel(**kw), sel_flip(**kw))})
    per_class = []
    for cls in classes:
        for m in METHODS:
            per_class.append({"class": cls, "method": m, **stats(sel(outlier=ACCEPT[0], depth_err=ACCEPT[1], method=m,
                                                                      **{"class": cls}))})  # fmt: skip
    rt = np.array([r["transfer_s"] for r in runtime]) if runtime else np.zeros(1)
    pt = np.array([r["perception_s"] for r in runtime]) if runtime else np.zeros(1)
    gt_ = np.array([r["generation_s"] for r in runtime]) if runtime else np.zeros(1)

    print("\nContact position error (cm), all classes; n = contacts scored")
    print(f"{'outliers':>8} {'depth err':>9}  {'method':<17} {'n':>5} {'median':>7} {'p90':>7} {'>6cm%':>6} "
          f"{'>15cm%':>6} {'flip%':>6}")  # fmt: skip
    for r in table:
        print(f"{r['outlier']:>8.0%} {r['depth_err']:>9.0%}  {r['method']:<17} {r['n']:>5} {r['median_cm']:>7.2f} "
              f"{r['p90_cm']:>7.2f} {r['over6_pct']:>6.1f} {r['over15_pct']:>6.1f} {r['flip_pct']:>6.1f}")  # fmt: skip
    print(f"\nPer class at {ACCEPT[0]:.0%} outliers, {ACCEPT[1]:.0%} depth scale error (median / p90, cm)")
    for r in per_class:
        print(f"  {r['class']:<8} {r['method']:<17} n={r['n']:>4}  {r['median_cm']:6.2f} / {r['p90_cm']:6.2f}")
    acc = {r["method"]: r for r in table if (r["outlier"], r["depth_err"]) == ACCEPT}
    ratio_med = acc["unaware"]["median_cm"] / acc["aware_similarity"]["median_cm"]
    ratio_p90 = acc["unaware"]["p90_cm"] / acc["aware_similarity"]["p90_cm"]
    ok = acc["aware_similarity"]["median_cm"] <= 3.0 and acc["aware_similarity"]["p90_cm"] <= 6.0
    print(f"\nAcceptance ({ACCEPT[0]:.0%} outliers, {ACCEPT[1]:.0%} depth scale error): geometry-aware median "
          f"{acc['aware_similarity']['median_cm']:.2f} cm (<= 3), p90 {acc['aware_similarity']['p90_cm']:.2f} cm (<= 6): "
          f"{'PASS' if ok else 'FAIL'}; geometry-unaware/aware ratio: median x{ratio_med:.1f}, p90 x{ratio_p90:.1f}")
    print(f"Similarity vs rigid SVD at the acceptance point: median {acc['aware_similarity']['median_cm']:.2f} vs "
          f"{acc['aware_rigid']['median_cm']:.2f} cm, p90 {acc['aware_similarity']['p90_cm']:.2f} vs {acc['aware_rigid']['p90_cm']:.2f} cm")
    print(f"Runtime per subtask (geometry-aware): contact transfer median {np.median(rt):.2f} s, p90 "
          f"{np.percentile(rt, 90):.2f} s, max {rt.max():.2f} s (< 2 s: {'PASS' if np.median(rt) < 2 else 'FAIL'}); "
          f"all perception after generation median {np.median(pt):.2f} s; synthetic generation median {np.median(gt_):.2f} s")
    stage_keys = [k for k in (runtime[0] if runtime else {}) if k not in ("transfer_s", "perception_s", "generation_s")]
    print("Time per subtask by stage (median s, geometry-aware): " +
          ", ".join(f"{k[:-2]} {np.median([r[k] for r in runtime]):.3f}" for k in stage_keys))
    print(f"Failed transfers: {len(failures)}" + "".join(f"\n  {f}" for f in failures[:10]))
    print(f"Total {time.perf_counter() - t0:.0f} s")

    with open(out / "errors.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["class"])
        w.writeheader()
        w.writerows(rows)
    (out / "results.json").write_text(json.dumps({
        "demos_per_class": args.demos, "classes": classes, "grid": args.grid, "table": table, "per_class": per_class,
        "acceptance": {"setting": ACCEPT, "pass": bool(ok), "unaware_over_aware_median": ratio_med,
                       "unaware_over_aware_p90": ratio_p90},
        "runtime_s": {"transfer_median": float(np.median(rt)), "transfer_p90": float(np.percentile(rt, 90)),
                      "perception_median": float(np.median(pt)), "generation_median": float(np.median(gt_))},
        "stage_median_s": {k[:-2]: float(np.median([r[k] for r in runtime])) for k in stage_keys},
        "startup": startup, "failures": failures}, indent=1))  # fmt: skip
    figure(out / "contact_transfer.png", fig_rows)
    if args.docs_figure:
        figure(Path(args.docs_figure), fig_rows)
    plot(out / "error_vs_outliers.png", table)
    print(f"Wrote {out}")
    return 0


def plot(path: Path, table: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=100)
    styles = {"aware_similarity": ("tab:green", "geometry-aware (similarity)"),
              "aware_rigid": ("tab:olive", "geometry-aware (rigid)"), "unaware": ("tab:red", "geometry-unaware")}
    for m, (c, name) in styles.items():
        rs = sorted((r for r in table if r["method"] == m and r["depth_err"] == ACCEPT[1]), key=lambda r: r["outlier"])
        if len(rs) < 2:
            continue
        x = [100 * r["outlier"] for r in rs]
        ax.plot(x, [r["median_cm"] for r in rs], "-o", color=c, label=f"{name}, median")
        ax.plot(x, [r["p90_cm"] for r in rs], "--", color=c, alpha=0.7, label=f"{name}, p90")
    ax.axhline(3.0, color="grey", lw=0.8, ls=":")
    ax.axhline(6.0, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("matcher outlier rate (%)")
    ax.set_ylabel("contact position error (cm)")
    ax.set_title(f"Contact transfer error, {ACCEPT[1]:.0%} depth scale error (synthetic demos)")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    sys.exit(main())
