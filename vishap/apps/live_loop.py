"""The live loop: the demo's core on a real clock (issue 9 parts 1 and 3; VisHap §2).

This process: source frames → vision → the core's scene step (:class:`~vishap.runtime.core.SceneStep`,
the same as the batch demo's) → the target record, published through a shared-memory latest-value
mailbox. The servo process (:class:`vishap.runtime.live.LiveServo`, SCHED_FIFO where permitted):
the same :class:`~vishap.apps.cycle.ServoCycle` as the batch demo — the finger on a simulated
device, guard → force law and Λ → controller → device, and the tactile sleeve — at 1 kHz on the
newest record. Frames never cross into the servo process, only the record does.

Times are on the servo's clock (:meth:`LiveServo.now`): a record's ``made_at`` is the servo time at
which its frame was grabbed, so the guard's staleness test measures the whole camera → target age.
A recorded source (a folder or video) is paced at its own time stamps, so the same loop replays a
recording in real time. Both processes write into one log with the batch demo's schema
(``vision`` and ``scene`` here, ``servo`` and ``tactile`` there), so summary, plots and replay read it.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from vishap._core.results import to_jsonable
from vishap.apps.config import DemoConfig
from vishap.apps.cycle import Finger
from vishap.apps.log import SignalLog, write_frame_png

__all__ = ["run_live_loop", "LiveCycle", "recorded_finger"]

#: the servo process's state record: [t, device contact point (3), guard action code, record seq]
STATE_SIZE = 9  # t, device point (3), guard code, record seq, joint angles (3)


class LiveCycle:
    """The servo process's object: unpacks the mailbox and runs the shared :class:`ServoCycle`.

    The mailbox holds the packed :class:`TargetRecord` followed by one transport field: the offset
    from the servo's clock to a recorded source's own time (for a recorded ground-truth finger).
    """

    def __init__(self, cfg: dict, device: str, finger: tuple | None):
        from vishap.apps.assemble import make_cycle
        from vishap.apps.cycle import RecordedFinger, TrackedFinger
        from vishap.runtime.core import GUARD_CODES, RECORD_SIZE, TargetRecord
        from vishap.world.scene import load_scene

        self.cfg = DemoConfig.model_validate(cfg)
        scene = load_scene(self.cfg.scene)
        self.log = SignalLog()
        if device != "sim":
            fing = None
        elif finger is None:
            fing = TrackedFinger()
        else:
            fing = RecordedFinger(*finger)
        self.cycle = make_cycle(self.cfg, scene, self.log, device=device, finger=fing)
        self.finger = fing
        self._n = RECORD_SIZE
        self._unpack = TargetRecord.unpack
        self._n_subjects = len(scene.objects)
        self._rec = TargetRecord()   # before the first write: idle, the arm held where it is
        self._good = self._rec       # the newest record that unpacked as valid
        self._raw_seq = None         # the counter field of the newest values read
        self._out = np.zeros(STATE_SIZE)
        self._guard_codes = GUARD_CODES

    def step(self, t: float, target) -> np.ndarray:
        # ``target`` is None until the vision process's first write. Anything written is judged by
        # TargetRecord.unpack: values no scene step writes (an all-zero record among them) are a
        # fault the guard counts and holds on (then retreats), keeping the newest good record's
        # subject and flags so a pressed surface is not pulled away at once
        if target is not None and target[0] != self._raw_seq:
            self._raw_seq = float(target[0])
            rec = self._unpack(target[: self._n], self._n_subjects)
            if rec.valid:
                self._good = self._rec = rec
                if self.finger is not None and hasattr(self.finger, "offset") and np.isfinite(target[self._n]):
                    self.finger.offset = float(target[self._n])
            else:
                self._rec = dataclasses.replace(self._good, valid=False)
        self.cycle.servo(t, self._rec)
        self.cycle.tactile(t)
        out = self._out
        _, p_dev, _, _ = self.cycle.last
        out[0] = t
        out[1:4] = p_dev
        out[4] = self._guard_codes[self.cycle.step.last_action]
        out[5] = self._rec.seq
        out[6:9] = self.cycle.last_q
        return out

    def finish(self) -> dict:
        c = self.cycle
        lim = c.step.device.limits
        return {"channels": self.log.channels, "stats": dict(c.stats), "guard_counts": dict(c.step.guard.counts),
                "wall": dict(c.wall), "peak_force_n": float(lim.peak_force_n),
                "continuous_force_n": float(lim.continuous_force_n), "hold_friction_n": c.step.contact.hold_friction_n,
                "hold_ramp_m": c.step.contact.hold_ramp_m}


def _live_view(rig, T_robot_cam, scene, vision):
    """The augmented view in a window where a display exists (it says once when there is none)."""
    from vishap.ar import ARCompositor, device_geometry
    from vishap.ar.live_view import open_live_view

    view = open_live_view()
    if not view.available:
        return None, view
    po = scene.passive_object
    geo = device_geometry("phantom_premium_1_0", passive_size_m=po.size_m, mount_offset_robot=po.mount_offset_m,
                          stand_z_m=None)
    return ARCompositor(rig, T_robot_cam, scene, geo, segmenter=vision.segmenters["left"]), view


def _make_live_cycle(cfg: dict, device: str, finger):
    return LiveCycle(cfg, device, finger)


def recorded_finger(gt: dict, normal, tip_radius_m: float):
    """``(t, pad point, velocity, finger direction)`` of a recording's ground truth (``gt.npz``)."""
    n = np.asarray(normal, float)
    pad = np.asarray(gt["tip_robot"], float) - tip_radius_m * n
    d = np.asarray(gt["finger_dir_robot"], float)
    return (np.asarray(gt["t"], float), pad, np.asarray(gt["finger_velocity_robot"], float),
            tuple(np.median(d, axis=0)) if d.ndim == 2 and len(d) else None)


class _Prefetcher:
    """A recording's frames read ahead in a thread (image decoding releases the GIL), so that reading
    files costs the loop no frame period; :meth:`wait_filled` gives a slow reader a head start."""

    def __init__(self, source, depth: int):
        import collections
        import threading

        self.depth = max(2, int(depth))
        self.frames = collections.deque()
        self.cond = threading.Condition()
        self.done = False
        self.error: BaseException | None = None
        self._stop = False
        self.thread = threading.Thread(target=self._read, args=(source,), daemon=True)
        self.thread.start()

    def _read(self, source) -> None:
        try:
            for f in source:
                with self.cond:
                    while len(self.frames) >= self.depth and not self._stop:
                        self.cond.wait(0.1)
                    if self._stop:
                        return
                    self.frames.append(f)
                    self.cond.notify_all()
        except BaseException as exc:  # handed to the loop, which raises it
            self.error = exc
        finally:
            with self.cond:
                self.done = True
                self.cond.notify_all()

    def wait_filled(self) -> None:
        with self.cond:
            while len(self.frames) < self.depth and not self.done:
                self.cond.wait(0.1)

    def pop(self):
        """The next frame (blocks); None at the end."""
        with self.cond:
            while not self.frames and not self.done:
                self.cond.wait(0.1)
            if self.error is not None:
                raise self.error
            if not self.frames:
                return None
            f = self.frames.popleft()
            self.cond.notify_all()
            return f

    def peek(self):
        with self.cond:
            return self.frames[0] if self.frames else None

    def close(self) -> None:
        with self.cond:
            self._stop = True
            self.cond.notify_all()
        self.thread.join(timeout=5)


def _frames(source, pace: bool, camera_hz: float, anchor: list):
    """``(frame, late)`` pairs. A camera's frames come as its driver delivers them (it keeps the newest).
    A recording is paced at its own time stamps after a head start of 2 s of frames read ahead; a frame
    is ``late`` (to be dropped) when the next one is already due — latest-value semantics, as a camera
    driver drops the frames nobody read. ``anchor`` = [recording time, monotonic time] of the
    recording's clock: set by the first frame, and reset by the caller when that frame is through."""
    if not pace:
        for f in source:
            yield f, False
        return
    pf = _Prefetcher(source, depth=int(2.0 * camera_hz))
    try:
        pf.wait_filled()
        while (f := pf.pop()) is not None:
            if anchor[0] is None:
                anchor[:] = [f.t, time.monotonic()]
            t_first, wall0 = anchor
            wait = wall0 + (f.t - t_first) - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            nxt = pf.peek()
            yield f, nxt is not None and time.monotonic() >= wall0 + (nxt.t - t_first)
    finally:
        pf.close()


def _frame_to_target_ms(vis: dict) -> float | None:
    """Median age of a frame when its target record was published (servo clock), processed frames only."""
    ok = ~vis["dropped"].astype(bool) if len(vis.get("t", [])) else np.zeros(0, bool)
    return float(np.median(1e3 * (vis["available_at"][ok] - vis["t"][ok]))) if ok.any() else None


def _dropped_row(t, k, mount, state) -> dict:
    nan2, nan3 = np.full(2, np.nan), np.full(3, np.nan)
    return {"t": t, "index": k, "dropped": True, "found": False, "lost": False, "p_cam": nan3, "uv_left": nan2,
            "uv_right": nan2, "confidence": 0.0, "vision_ms": np.nan, "available_at": np.nan, "tip_cam_true": nan3,
            "tip_robot_true": nan3, "tip_visible": False, "hand_visible": False, "render_ms": np.nan,
            "device_q": nan3, "device_ee": state[1:4] - mount, "segment_ms": np.nan, "detect_ms": np.nan,
            "stereo_ms": np.nan}


def run_live_loop(cfg: DemoConfig, *, out, source, rig, T_robot_cam, calib_report: dict | None = None,
                  device: str = "sim", gt: dict | None = None, duration_s: float = 30.0, realtime: bool = True,
                  pace: bool | None = None, source_name: str | None = None, progress: bool = False) -> dict:
    """Run until ``duration_s`` or the source ends; write the demo's outputs into ``out``.

    ``gt`` (a recording's ground truth) drives the simulated finger when ``device == "sim"`` and gives
    the vision-accuracy figures; the system itself never reads it.
    """
    from vishap.apps.assemble import TIP_RADIUS_M, make_scene_step, make_world, meta, vision_result
    from vishap.apps.loop import _stage_ms, log_scene_row
    from vishap.apps.summary import write_outputs
    from vishap.runtime.core import RECORD_SIZE
    from vishap.runtime.live import LiveServo
    from vishap.vision.capture import CameraSource, StereoFrame
    from vishap.vision.pipeline import VisionPipeline
    from vishap.world.scene import load_scene

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene(cfg.scene)
    T = None if T_robot_cam is None else np.asarray(T_robot_cam, float)
    finger = None
    if gt is not None and device == "sim":
        finger = recorded_finger(gt, scene.objects[0].normal, TIP_RADIUS_M)
    servo = LiveServo(functools.partial(_make_live_cycle, cfg.model_dump(), device, finger),
                      target_size=RECORD_SIZE + 1, state_size=STATE_SIZE, realtime=realtime)
    vision = VisionPipeline(rig)
    world = make_world(cfg, scene, rig, T)
    scene_step = make_scene_step(world, T)
    mount = scene_step.mount
    pace = (not isinstance(source, CameraSource)) if pace is None else pace
    log = SignalLog(meta(cfg, rig=rig, T_true=None if gt is None else gt.get("T_robot_cam"), T_est=T,
                         calib_report=calib_report or {}, scene=scene, force_limit_n=float("nan"),
                         continuous_force_n=float("nan"), mode="live", source=source_name, device=device))
    if finger is not None and finger[3] is not None:
        log.meta["sleeve_finger_dir"] = finger[3]
    else:
        log.meta["sleeve_finger_dir"] = Finger.finger_dir if device == "sim" else None
    gt_index = {}
    if gt is not None:
        gt_index = {round(float(t), 6): i for i, t in enumerate(gt["t"])}
    vis_ch = log.channel("vision")
    dropped_frames: list[int] = []  # frames dropped here (counted with the guard's fault events)
    offset = np.nan
    # lossless frames for replay are written beside the loop (PNG encoding of a noisy pair takes longer
    # than a frame period here; OpenCV releases the GIL while it encodes)
    writer = ThreadPoolExecutor(max_workers=1) if cfg.save_frames else None
    ar, view = _live_view(rig, T, scene, vision)
    from vishap._core.results import progress as bar

    servo.start()
    wall0 = time.monotonic()
    shown = bar(total=round(duration_s), desc=f"demo {cfg.scene} (live)", unit="s", quiet=not progress)
    try:
        anchor = [None, None]
        for k, (frame, late) in enumerate(_frames(source, pace, cfg.camera_hz, anchor)):
            elapsed = time.monotonic() - wall0
            if elapsed > duration_s:
                break
            if int(elapsed) > shown.n:  # whole seconds: the bar is redrawn at most once a second
                shown.update(int(elapsed) - shown.n)
            state, _ = servo.read_state()
            t = servo.now()  # the servo's clock at the grab, right also while the servo process is starved
            if not np.isfinite(offset):
                offset = frame.t - t
            if late:  # the next frame is already due: drop this one, so that the targets stay fresh
                vis_ch.append(**_dropped_row(t, k, mount, state))
                dropped_frames.append(k)
                continue
            if writer is not None:
                writer.submit(write_frame_png, out / "frames", "left", k, frame.left)
                writer.submit(write_frame_png, out / "frames", "right", k, frame.right)
            est = vision.process(StereoFrame(k, t, frame.left, frame.right))
            res = vision_result(est)
            p_dev = state[1:4].copy()
            c0 = time.perf_counter()
            rec, inter, p_pad = scene_step.step(t, res["found"], res["p_cam"], res["confidence"],
                                                p_dev if state[0] > 0 else None,
                                                calibrated=T is not None, lost=res["lost"])
            world_ms = 1e3 * (time.perf_counter() - c0)
            servo.write_target(np.append(rec.pack(), offset))
            now = servo.now()  # the record is published: the frame's age is now - t
            if view.available:
                view.show(ar.compose(frame.left, None, state[6:9], t))
            log_scene_row(log, t, rec, inter, p_pad, p_dev, mount, world_ms)
            g = gt_index.get(round(float(frame.t), 6))
            tip_cam = np.full(3, np.nan) if g is None else np.asarray(gt["tip_cam"][g], float)
            tip_vis = False if g is None else bool(gt["tip_visible_left"][g] and gt["tip_visible_right"][g])
            if k == 0 and pace:
                # the recording's clock starts once its first frame is through: the first pass of
                # vision and the world (imports, allocations) can take seconds on a loaded machine
                anchor[:] = [frame.t, time.monotonic()]
                offset = frame.t - servo.now()
            vis_ch.append(t=t, index=k, dropped=False, found=res["found"], lost=res["lost"], p_cam=res["p_cam"], uv_left=res["uv_left"],
                          uv_right=res["uv_right"], confidence=res["confidence"], vision_ms=res["vision_ms"],
                          available_at=now, tip_cam_true=tip_cam,
                          tip_robot_true=np.full(3, np.nan) if g is None else np.asarray(gt["tip_robot"][g], float),
                          tip_visible=tip_vis, hand_visible=True if g is None else bool(gt["hand_visible"][g]),
                          render_ms=np.nan, device_q=np.full(3, np.nan), device_ee=p_dev - mount,
                          **_stage_ms(est.timings))
    finally:
        shown.close()
        view.close()
        report = servo.stop()
        close = getattr(source, "close", None)
        if close:
            close()
        if writer is not None:
            writer.shutdown(wait=True)
    res = report.result
    log.channels.update(res["channels"])
    # the device's limits as its driver reports them at start-up
    log.meta["force_limit_n"], log.meta["continuous_force_n"] = res["peak_force_n"], res["continuous_force_n"]
    log.meta["hold_friction_n"], log.meta["hold_ramp_m"] = res["hold_friction_n"], res["hold_ramp_m"]
    res["guard_counts"]["frame_dropped"] += len(dropped_frames)
    summary = write_outputs(out, log, stats={**res["stats"], "frames_dropped": len(dropped_frames)},
                            guard_counts=res["guard_counts"])
    summary.update(mode="live", device=device, source=source_name, servo_realtime=report.realtime,
                   servo_sched_fifo=report.sched_fifo, servo_steps=report.steps,
                   servo_step_us_median=report.step_us_median, servo_lateness=report.lateness,
                   frame_to_target_ms_median=_frame_to_target_ms(log.channel("vision").arrays()))
    summary = to_jsonable(summary)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
