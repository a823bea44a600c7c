"""The live loop: cameras → vision → registration → world in this process, the guarded 1 kHz servo
in its own real-time process (:class:`vishap.runtime.live.LiveServo`), joined by shared-memory
latest-value mailboxes (issue 9 parts 1 and 3; VisHap §2).

Frames never cross into the servo process: only the 6-value target record
``[x, y, z, made_at, confidence, calibrated]`` does (:mod:`vishap.runtime.device_servo`). Times are
on the servo's clock (:meth:`LiveServo.now`): a target's ``made_at`` is the servo time at which its frame was grabbed, so
the guard's staleness test measures the whole camera → target age. A non-camera source (a recorded
folder or video) is paced at its own time stamps, so the same loop replays a recording in real time.
"""
from __future__ import annotations

import functools
import importlib
import json
import time
from pathlib import Path

import numpy as np

from vishap.apps.log import SignalLog
from vishap.bench._common import to_jsonable

__all__ = ["run_live_loop", "make_guarded_servo"]

TIP_RADIUS_M = 0.008  # the fingertip cap radius the synthetic hand and the world assume (m)


def make_guarded_servo(device_path: str, passive_object: tuple | None = None):
    """Build the device (``"module:Class"``), its controller and the guarded servo (runs in the child)."""
    from vishap.robot.controller import Controller
    from vishap.robot.travel import TravelLimiter
    from vishap.runtime.device_servo import DeviceServo

    mod, cls = device_path.split(":")
    device_cls = getattr(importlib.import_module(mod), cls)
    if passive_object is not None:
        from vishap.robot.mjcf import PassiveObject

        device = device_cls(passive_object=PassiveObject(*passive_object))
    else:
        device = device_cls()
    return DeviceServo(device, Controller(device.params, limits=device.limits), travel=TravelLimiter())


def run_live_loop(scene: str, *, out, source, rig, T_robot_cam, device_path: str, duration_s: float,
                  mount_offset=(0.030, 0.0, 0.0), realtime: bool = True, pace: bool | None = None) -> dict:
    """Run until ``duration_s`` or the source ends; write ``log.npz`` and ``summary.json`` into ``out``."""
    from vishap.runtime.device_servo import STATE_SIZE, TARGET_SIZE, target_record
    from vishap.runtime.live import LiveServo
    from vishap.vision.capture import CameraSource, StereoFrame
    from vishap.vision.pipeline import VisionPipeline
    from vishap.world.scene import load_scene
    from vishap.world.world import World

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sc = load_scene(scene)
    n = np.asarray(sc.objects[0].normal, float)
    mount = np.asarray(mount_offset, float)
    T = np.asarray(T_robot_cam, float)
    po = sc.passive_object
    po_args = ("plate", tuple(po.size_m), po.mass_kg) if po.shape != "sphere" else ("sphere", (po.size_m[0] / 2,), po.mass_kg)
    servo = LiveServo(functools.partial(make_guarded_servo, device_path, po_args if "plant" in device_path else None),
                      target_size=TARGET_SIZE, state_size=STATE_SIZE, realtime=realtime)
    vision = VisionPipeline(rig)
    world = None
    pace = (not isinstance(source, CameraSource)) if pace is None else pace
    log = SignalLog({"format": "vishap.live_log/1", "scene": scene, "T_robot_cam": T, "mount_offset": mount})
    ch = log.channel("frames")
    servo.start()
    try:
        wall0 = time.monotonic()
        from vishap.apps.assemble import stereo_noise_m
        from vishap.world.predictor import KalmanPredictor

        # frames are stamped at the grab on the servo's clock; the world predicts ahead by a typical
        # vision time (15 ms) and assumes the stereo model's noise at the calibrated camera distance
        world = World(sc, predictor=KalmanPredictor(meas_std_m=stereo_noise_m(rig, T, sc.objects[0].centre)),
                      latency_s=0.015)
        t_first = None
        armed = False
        for k, frame in enumerate(source):
            grabbed = time.monotonic()
            if t_first is None:
                t_first = frame.t
            if pace:  # a recording: wait for the frame's own time
                wait = (frame.t - t_first) - (grabbed - wall0)
                if wait > 0:
                    time.sleep(wait)
                grabbed = time.monotonic()
            if grabbed - wall0 > duration_s:
                break
            state, _ = servo.read_state()
            t = servo.now()  # the servo's clock at the grab, right also while the servo process is starved
            est = vision.process(StereoFrame(k, t, frame.left, frame.right))
            p_dev = state[1:4] + mount
            pad = np.full(3, np.nan)
            X = np.full(3, np.nan)
            if est.found and est.p_cam is not None:
                pad = np.asarray(est.p_cam, float) @ T[:3, :3].T + T[:3, 3] - TIP_RADIUS_M * n
                inter = world.update(t, pad, p_dev)
                armed = True
            elif armed:
                inter = world.update(t, None, p_dev)
            else:
                inter = None
            if inter is not None:
                X = np.asarray(inter.X_d, float) - mount
                servo.write_target(target_record(X, t, float(est.confidence), True))
            ch.append(t=t, wall=grabbed - wall0, found=bool(est.found), confidence=float(est.confidence),
                      finger_robot=pad, X_d=X + mount, device=state[1:4].copy(), action=int(state[4]),
                      fault=int(state[5]), vision_ms=float(est.timings.get("total_ms", np.nan)),
                      age_ms=1e3 * (time.monotonic() - grabbed))
    finally:
        report = servo.stop()
        close = getattr(source, "close", None)
        if close:
            close()
    log.save(out / "log.npz")
    a = ch.arrays()
    summary = {
        "mode": "live",
        "scene": scene,
        "frames": len(ch),
        "vision_ms_per_pair": float(np.nanmedian(a["vision_ms"])) if len(ch) else None,
        "detection_rate": float(np.mean(a["found"])) if len(ch) else None,
        "frame_to_target_ms_median": float(np.median(a["age_ms"])) if len(ch) else None,
        "servo_realtime": report.realtime,
        "servo_sched_fifo": report.sched_fifo,
        "servo_steps": report.steps,
        "servo_step_us_median": report.step_us_median,
        "servo_lateness": report.lateness,
        "actions": {name: int(np.sum(a["action"] == i)) for i, name in enumerate(("track", "hold", "retreat"))} if len(ch) else {},
    }
    summary = to_jsonable(summary)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
