"""``vishap bench runtime``: the live 1 kHz servo period while vision runs (issue 9).

The servo runs in its own process (:mod:`vishap.runtime.live`) stepping the MuJoCo PHANToM under
the guarded controller; this process plays camera + vision + world: it pushes stereo frames
through the real :class:`~vishap.vision.pipeline.VisionPipeline` at camera rate and publishes each
fix as a device target through the shared-memory mailbox. Configurations, measured one after the
other in one run: best-effort scheduling vs SCHED_FIFO, with and without vision load, with and
without pinning the servo to its own CPU. Goal: p99 lateness ≤ 100 µs and fewer than 0.1 % of
ticks more than 1 ms late (missed periods count as late).
"""
from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure
from vishap.robot.params import WORKSPACE_MAX, WORKSPACE_MIN

HELP = "live servo lateness (p99, >1 ms fraction) while vision runs; SCHED_FIFO vs best-effort"


@dataclass(frozen=True)
class Config:
    name: str
    realtime: bool
    vision: bool
    pin: bool


CONFIGS = (
    Config("best_effort_vision", realtime=False, vision=True, pin=False),
    Config("fifo_idle", realtime=True, vision=False, pin=False),
    Config("fifo_vision", realtime=True, vision=True, pin=False),
    Config("fifo_vision_pinned", realtime=True, vision=True, pin=True),
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seconds", type=float, default=6.0, help="run time per configuration (s)")
    p.add_argument("--frames", type=int, default=40, help="distinct stereo frames the vision load cycles through")
    p.add_argument("--camera-hz", type=float, default=30.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--configs", default=",".join(c.name for c in CONFIGS),
                   help="comma-separated subset of " + ", ".join(c.name for c in CONFIGS))


def _frames(n: int, seed: int):
    """Rendered 640×480 stereo frames of the wall scene: 10 hand-free frames, then a finger
    descending onto the wall beside the device. Returns (frames, rig, T_robot_cam)."""
    from vishap.robot.kinematics import ik, link_points
    from vishap.sim.camera_placement import default_T_robot_cam
    from vishap.sim.renderer import StereoRenderer
    from vishap.sim.state import FrameState
    from vishap.vision.rig import StereoRig

    rig = StereoRig.from_fov(640, 480, 60.0, 0.06)
    T = default_T_robot_cam()
    ee = np.array([0.20, 0.0, -0.16])
    pts = link_points(ik(ee))
    frames = []
    with StereoRenderer(rig, T, "wall", seed=seed) as r:
        for k in range(n):
            s = max(0, k - 10) / max(1, n - 11)
            tip = np.array([0.21 + 0.02 * s, 0.01 - 0.02 * s, -0.08 - 0.06 * s])
            frames.append(r.render(FrameState(k / 30.0, tip, hand_visible=k >= 10,
                                              device_points_robot=pts, ee_robot=ee)))
    return frames, rig, T


def _run_config(cfg: Config, seconds: float, frames, rig, T_robot_cam, camera_hz: float) -> dict:
    import functools
    import os

    from vishap.apps.config import DemoConfig
    from vishap.apps.live_loop import STATE_SIZE, _make_live_cycle
    from vishap.runtime.core import RECORD_SIZE, TargetRecord
    from vishap.runtime.live import LiveServo
    from vishap.vision.capture import StereoFrame
    from vishap.vision.pipeline import VisionPipeline

    ncpu = os.cpu_count() or 1
    servo_cpu = ncpu - 1 if (cfg.pin and ncpu > 1) else None
    # the live mode's servo process: the demo's servo cycle (guard, laws, controller, plant, sleeve)
    servo = LiveServo(functools.partial(_make_live_cycle, DemoConfig(scene="wall").model_dump(), "sim", None),
                      target_size=RECORD_SIZE + 1, state_size=STATE_SIZE, realtime=cfg.realtime, cpu=servo_cpu)
    seq = [0]

    def target_record(x, made_at, confidence):
        seq[0] += 1
        return np.append(TargetRecord(seq[0], tuple(x), made_at, confidence, True, True, 0).pack(), np.nan)

    old_affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    if servo_cpu is not None:
        os.sched_setaffinity(0, set(range(ncpu)) - {servo_cpu})
    vision = VisionPipeline(rig)
    R, t = T_robot_cam[:3, :3], T_robot_cam[:3, 3]
    vision_ms = []
    servo.start()
    try:
        period = 1.0 / camera_hz
        t0 = time.monotonic()
        k = 0
        last = np.array([0.2, 0.0, -0.12])
        while (now := time.monotonic() - t0) < seconds:
            if cfg.vision:
                f = frames[k % len(frames)]
                c0 = time.perf_counter()
                est = vision.process(StereoFrame(k, now, f.left, f.right))
                vision_ms.append((time.perf_counter() - c0) * 1e3)
                if est.found:
                    last = np.clip(R @ est.p_cam + t, WORKSPACE_MIN, WORKSPACE_MAX)
                servo.write_target(target_record(last, servo.now(), 1.0))
            else:
                servo.write_target(target_record(last, servo.now(), 1.0))
            k += 1
            sleep = (k * period) - (time.monotonic() - t0)
            if sleep > 0:
                time.sleep(sleep)
    finally:
        report = servo.stop()
        if old_affinity is not None:
            os.sched_setaffinity(0, old_affinity)
    rec = {"config": cfg.name, "sched_fifo": report.sched_fifo, "realtime": report.realtime,
           "pinned_cpu": servo_cpu, "vision": cfg.vision, "servo_step_us_median": report.step_us_median,
           "vision_frames": len(vision_ms),
           "vision_ms_median": float(np.median(vision_ms)) if vision_ms else None}
    rec.update(report.lateness)
    rec["_lateness_s"] = report.lateness_s
    return rec


def run(args: argparse.Namespace) -> dict:
    wanted = [c.strip() for c in args.configs.split(",") if c.strip()]
    known = {c.name: c for c in CONFIGS}
    unknown = [w for w in wanted if w not in known]
    if unknown:
        raise SystemExit(f"bench runtime: unknown config(s) {unknown}; known: {sorted(known)}")
    frames, rig, T_robot_cam = _frames(args.frames, args.seed)
    from vishap._core.results import progress

    records = [_run_config(known[w], args.seconds, frames, rig, T_robot_cam, args.camera_hz)
               for w in progress(wanted, desc="bench runtime", unit="config", quiet=getattr(args, "quiet", False))]
    out = Path(args.out)
    fig, (ax1, ax2) = new_figure(1, 2, figsize=(11, 4))
    for r in records:
        x = np.sort(r.pop("_lateness_s")) * 1e6
        if x.size:
            ax1.semilogx(np.maximum(x, 0.1), 1.0 - np.arange(x.size) / x.size, label=r["config"])
    ax1.axvline(100, color="k", ls="--", lw=0.8)
    ax1.axvline(1000, color="r", ls=":", lw=0.8)
    ax1.set_xlabel("servo tick lateness (µs)")
    ax1.set_ylabel("fraction of ticks later than x")
    ax1.set_yscale("log")
    ax1.legend(fontsize=8)
    names = [r["config"] for r in records]
    ax2.bar(names, [r.get("lateness_us_p99", np.nan) for r in records])
    ax2.axhline(100, color="k", ls="--", lw=0.8, label="goal p99 ≤ 100 µs")
    ax2.set_yscale("log")
    ax2.set_ylabel("p99 lateness (µs)")
    ax2.tick_params(axis="x", rotation=20)
    ax2.legend(fontsize=8)
    save_figure(fig, out / "runtime.png")
    main = next((r for r in records if r["config"] == "fifo_vision_pinned"), records[-1])
    return {
        "servo_lateness_us_p99": main.get("lateness_us_p99"),
        "servo_late_over_1ms_fraction": main.get("late_over_1ms_fraction"),
        "goal_met": bool(main.get("lateness_us_p99", np.inf) <= 100 and main.get("late_over_1ms_fraction", 1) < 1e-3),
        "configs": records,
        "seconds_per_config": args.seconds,
        "machine": machine_info(),
        "chart": str(out / "runtime.png"),
    }
