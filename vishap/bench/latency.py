"""``vishap bench latency``: the end-to-end latency budget, camera frame → force update, per stage.

A short wall demo runs (or an existing demo log is read with ``--log``); its log holds, per frame,
the measured vision time per stage (segmentation, detection, stereo), per scene update the
registration + world time, and per servo tick the servo cycle time. The budget adds to these
measured costs the hand-over waits that the loop rates impose on the same frames: a vision result
waits for the next scene tick (60 Hz by default), the new target for the next servo tick (1 kHz).
The same frames are also budgeted for the alternatives a user would pick: a scene loop at the
camera's 30 Hz, and an event-driven scene update (1 kHz, i.e. the world runs as soon as vision
returns). Rendering (the simulated camera) is not part of the budget; exposure and readout of a
real camera would add to it (not modelled).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

HELP = "end-to-end latency budget camera frame -> force update, per stage (chart)"
QUICK_ARGS = ["--frames", "60"]

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run", "budget"]

STAGES = ("segment", "detect", "stereo", "wait for scene tick", "registration + world", "wait for servo tick",
          "servo cycle")


def add_arguments(parser) -> None:
    parser.add_argument("--log", default=None, help="read this demo log instead of running a demo")
    parser.add_argument("--frames", type=int, default=90, help="frames of the demo to run (default 90)")
    parser.add_argument("--width", type=int, default=480)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--seed", type=int, default=0)


def _next_tick(t_s: np.ndarray, rate_hz: float, base_hz: float = 1000.0) -> np.ndarray:
    """Time of the first run of a ``rate_hz`` task at or after ``t_s`` on the base-rate grid
    (the :class:`~vishap.runtime.MultiRateScheduler` rule: run k at base tick ceil(k·base/rate))."""
    k = np.floor(t_s * rate_hz + 1e-9)
    late = np.ceil(k * base_hz / rate_hz - 1e-9) / base_hz < t_s - 1e-12
    k = np.where(late, k + 1, k)
    return np.ceil(k * base_hz / rate_hz - 1e-9) / base_hz


def budget(vis: dict, scene: dict, servo: dict, *, scene_hz: float, servo_hz: float = 1000.0) -> dict:
    """Per-frame latency of each stage (ms) for frames whose tip was found."""
    ok = vis["found"].astype(bool) & np.isfinite(vis["vision_ms"])
    t = vis["t"][ok]
    seg, det, st = (np.nan_to_num(vis[k][ok]) for k in ("segment_ms", "detect_ms", "stereo_ms"))
    vision_ms = vis["vision_ms"][ok]
    arrive = t + vision_ms / 1e3
    scene_at = _next_tick(arrive, scene_hz, servo_hz)
    wait_scene = 1e3 * (scene_at - arrive)
    world_ms = float(np.median(scene["world_ms"])) if len(scene.get("world_ms", [])) else 0.0
    target_at = scene_at + world_ms / 1e3
    servo_at = _next_tick(target_at, servo_hz, servo_hz)
    wait_servo = 1e3 * (servo_at - target_at)
    servo_ms = float(np.median(servo["tick_us"])) / 1e3
    parts = {
        "segment": seg, "detect": det, "stereo": st, "wait for scene tick": wait_scene,
        "registration + world": np.full(t.size, world_ms), "wait for servo tick": wait_servo,
        "servo cycle": np.full(t.size, servo_ms),
    }
    total = sum(parts.values())
    return {"frames": int(t.size), "parts": parts, "total": total}


def _stats(x) -> dict:
    x = np.asarray(x, float)
    if not x.size:
        return {"median": None, "p95": None}
    return {"median": float(np.median(x)), "p95": float(np.percentile(x, 95))}


def run(args) -> dict:
    from vishap.apps.log import load_log
    from vishap.bench._common import machine_info, new_figure, save_figure

    out = Path(args.out)
    if args.log:
        meta, ch = load_log(args.log)
        source = str(args.log)
    else:
        from vishap.apps import DemoConfig, run_demo

        cfg = DemoConfig(scene="wall", frames=args.frames, width=args.width, height=args.height, seed=args.seed,
                         video=False, save_frames=False)
        t0 = time.perf_counter()
        run_demo(cfg, out / "demo")
        meta, ch = load_log(out / "demo")
        source = f"wall demo, {args.frames} frames {args.width}x{args.height}, {time.perf_counter() - t0:.0f} s"
    cfg = meta["config"]
    configs = {f"scene {cfg['scene_hz']:g} Hz (default)": cfg["scene_hz"], "scene at camera rate (30 Hz)": cfg["camera_hz"],
               "event-driven scene (1 kHz)": cfg["servo_hz"]}
    results = {name: budget(ch["vision"], ch.get("scene", {}), ch["servo"], scene_hz=hz, servo_hz=cfg["servo_hz"])
               for name, hz in configs.items()}

    fig, (a1, a2) = new_figure(1, 2, figsize=(11.5, 4.0), gridspec_kw={"width_ratios": [1.6, 1]})
    names = list(results)
    colours = ["#4c72b0", "#55a868", "#c44e52", "#bbbbbb", "#8172b2", "#dddddd", "#ccb974"]
    for i, name in enumerate(names):
        left = 0.0
        for stage, c in zip(STAGES, colours):
            v = float(np.median(results[name]["parts"][stage])) if results[name]["frames"] else 0.0
            a1.barh(i, v, left=left, color=c, edgecolor="k", lw=0.3, label=stage if i == 0 else None)
            left += v
        p95 = _stats(results[name]["total"])["p95"] or 0.0
        a1.plot([p95], [i], "k|", ms=14)
        a1.text(left, i, f" {left:.1f} ms", va="center", fontsize=8)
    a1.set_yticks(range(len(names)))
    a1.set_yticklabels(names, fontsize=8)
    a1.set_xlabel("camera frame → force update (ms): median per stage; | = p95 of the total")
    a1.legend(fontsize=7, loc="lower right")
    a1.set_title("latency budget per stage")
    for name in names:
        tot = results[name]["total"]
        if len(tot):
            a2.hist(tot, bins=30, histtype="step", label=name)
    a2.set_xlabel("total latency per frame (ms)")
    a2.set_ylabel("frames")
    a2.legend(fontsize=7)
    a2.set_title("distribution over frames")
    chart = save_figure(fig, out / "latency.png")

    record = {"source": source, "machine": machine_info(), "chart": str(chart), "configs": {}}
    for name, r in results.items():
        record["configs"][name] = {
            "frames": r["frames"],
            "total_ms": _stats(r["total"]),
            "stages_ms": {k: _stats(v) for k, v in r["parts"].items()},
        }
    d = record["configs"][names[0]]
    record["total_ms_median"] = d["total_ms"]["median"]
    record["total_ms_p95"] = d["total_ms"]["p95"]
    record["vision_ms_median"] = float(np.nanmedian(ch["vision"]["vision_ms"])) if len(ch["vision"]["t"]) else None
    record["servo_cycle_us_median"] = float(np.median(ch["servo"]["tick_us"]))
    if not math.isfinite(record["vision_ms_median"] or float("nan")):
        record["vision_ms_median"] = None
    return record
