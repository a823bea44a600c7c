"""The batch demo: the whole system in one closed loop on a simulated clock (issue 9 part 2).

Per base tick (1 ms) the :class:`~vishap.runtime.MultiRateScheduler` runs, in this order:

``camera``  (30 Hz)  render the stereo pair *after* the physics reached the frame's time, showing the
                     scripted finger and the device where the MuJoCo plant is; run vision on it; the
                     estimate becomes available ``vision_latency_s`` later (VisHap §2.1);
``deliver`` (1 kHz)  hand due vision results to the scene (a latest-value hand-over);
``scene``   (60 Hz)  the core's scene step (:class:`~vishap.runtime.core.SceneStep`: registration,
                     Eq. 3, and :meth:`World.update`, §2.2) on the newest estimate → the target record;
``servo``   (1 kHz)  :meth:`ServoCycle.servo <vishap.apps.cycle.ServoCycle.servo>`: finger-pad contact
                     on the plant → the core's servo step (guard → force law and Λ → controller,
                     Eq. 4–9 → MuJoCo plant);
``tactile`` (1 kHz)  :meth:`ServoCycle.tactile <vishap.apps.cycle.ServoCycle.tactile>` (HAPTEX §II-C,
                     40 Hz pin update inside).

Live mode (:mod:`vishap.apps.live_loop`) runs the same scene step and servo cycle on a real clock,
the servo cycle in its own process. Ground truth (the scripted finger) drives only what is
physically the user's: the rendered hand and the pad's contact with the passive object. Everything
the system knows about the finger comes through the rendered pixels and the vision pipeline.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from vishap._core.pose import transform_points
from vishap.apps.assemble import vision_result
from vishap.apps.config import DemoConfig
from vishap.apps.log import SignalLog, write_frame_png

__all__ = ["Demo", "run_demo"]


class Demo:
    """One batch run; :meth:`run` then :meth:`finish` (writes every output)."""

    def __init__(self, cfg: DemoConfig, out, *, progress: bool = False):
        from vishap.apps import assemble
        from vishap.runtime import MultiRateScheduler
        from vishap.runtime.core import TargetRecord

        self.cfg = cfg
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.progress = progress
        self.bar = None  # the progress bar, while run() runs
        self.log = SignalLog()
        self.st = st = assemble.build(cfg, self.out, self.log)
        self.log.meta.update(assemble.meta(
            cfg, rig=st.rig, T_true=st.T_true, T_est=st.T_est, calib_report=st.calib_report, scene=st.scene,
            force_limit_n=st.force_limit_n, continuous_force_n=float(st.plant.limits.continuous_force_n),
            hold_friction_n=st.cycle.step.contact.hold_friction_n, hold_ramp_m=st.cycle.step.contact.hold_ramp_m),
            sleeve_finger_dir=st.cycle.finger.finger_dir)
        self.script = st.script
        self.n = np.asarray(st.scene_object.normal, float)
        self.frame_index = 0
        self.pending: list[tuple[float, dict]] = []   # (available_at, vision result)
        self.newest: dict | None = None               # vision → scene mailbox
        self.newest_seen = -1
        self.target = TargetRecord()                  # scene → servo mailbox (in-process)
        self.video = None
        if cfg.video:
            from vishap.apps.overlay import VideoWriter

            self.video = VideoWriter(self.out / "demo.mp4", cfg.camera_hz)
        self.ar = self.ar_video = None
        if cfg.video:  # the augmented view (VisHap §2 world subsystem): device deleted, objects drawn in
            from vishap.apps.overlay import VideoWriter
            from vishap.ar import ARCompositor, device_geometry

            po = st.scene.passive_object
            geo = device_geometry("phantom_premium_1_0", passive_size_m=po.size_m,
                                  mount_offset_robot=st.mount_offset, stand_z_m=None)
            self.ar = ARCompositor(st.rig, st.T_est, st.scene, geo, segmenter=st.vision.segmenters["left"],
                                   seed=cfg.seed)
            self.ar_video = VideoWriter(self.out / "ar.mp4", cfg.camera_hz)
        self.wall = {"render": 0.0, "vision": 0.0, "scene": 0.0, "io": 0.0}
        self.stats = {"frames_dropped": 0}

        self.sched = MultiRateScheduler(cfg.servo_hz)
        self.sched.add("camera", cfg.camera_hz, self.camera)
        self.sched.add("deliver", cfg.servo_hz, self.deliver)
        self.sched.add("scene", cfg.scene_hz, self.scene)
        self.sched.add("servo", cfg.servo_hz, lambda t: st.cycle.servo(t, self.target))
        self.sched.add("tactile", cfg.tactile_hz, st.cycle.tactile)

    # ------------------------------------------------------------------ helpers
    def _fault(self, kind: str, t: float) -> bool:
        return self.cfg.fault_active(kind, t)

    # ------------------------------------------------------------------ camera (30 Hz)
    def camera(self, t: float) -> None:
        k = self.frame_index
        if k >= self.cfg.frames:
            return
        self.frame_index += 1
        st = self.st
        dev = st.plant.read()
        tip = self.script.tip(t, st.tip_radius_m)
        visible = self.script.visible(t) and not self._fault("finger_lost", t)
        c0 = time.perf_counter()
        pair = st.render(t, tip_robot=tip, finger_dir=self.script.finger_dir, flexion=self.script.flexion,
                         hand_visible=visible, q=dev.q, ee=dev.p_robot)
        c1 = time.perf_counter()
        self.wall["render"] += c1 - c0
        tip_cam = transform_points(st.T_cam_robot_true, tip)
        uv_l, uv_r = st.rig.project(tip_cam)
        tip_vis = visible and _label_at(pair.labels_left, uv_l[0]) == 1 and _label_at(pair.labels_right, uv_r[0]) == 1
        if self.cfg.save_frames:
            write_frame_png(self.out / "frames", "left", k, pair.left)
            write_frame_png(self.out / "frames", "right", k, pair.right)
        dropped = self._fault("frames_dropped", t)
        row = {"t": t, "index": k, "dropped": dropped, "found": False, "lost": False, "p_cam": np.full(3, np.nan),
               "uv_left": np.full(2, np.nan), "uv_right": np.full(2, np.nan), "confidence": 0.0,
               "vision_ms": np.nan, "available_at": np.nan, "tip_cam_true": tip_cam, "tip_robot_true": tip,
               "tip_visible": tip_vis, "hand_visible": visible, "render_ms": 1e3 * (c1 - c0),
               "device_q": dev.q, "device_ee": dev.p_robot, **_stage_ms({})}
        if dropped:
            self.stats["frames_dropped"] += 1
            st.guard.count("frame_dropped")
        else:
            c2 = time.perf_counter()
            est = st.vision.process(st.StereoFrame(k, t, pair.left, pair.right))
            self.wall["vision"] += time.perf_counter() - c2
            res = vision_result(est)
            if self._fault("nan", t) and res["found"]:
                res["p_cam"] = np.full(3, np.nan)
            available = t + self.cfg.vision_latency_s
            for f in self.cfg.faults:
                if f.kind == "vision_stalled" and f.active(t):
                    available = max(available, f.t_end + self.cfg.vision_latency_s)
            self.pending.append((available, {"t": t, "index": k, **res}))
            row.update(found=res["found"], lost=res["lost"], p_cam=res["p_cam"], uv_left=res["uv_left"], uv_right=res["uv_right"],
                       confidence=res["confidence"], vision_ms=res["vision_ms"], available_at=available,
                       **_stage_ms(est.timings))
        self.log.channel("vision").append(**row)
        if self.video is not None:
            c3 = time.perf_counter()
            last = st.cycle.last
            f = 0.0 if last is None else float(np.linalg.norm(last[0]))
            extra = [f"device: {st.cycle.step.last_action}   contact force {f:4.2f} N"]
            self.video.write(st.overlay(pair, row, dev, self.target, t, extra))
            self.wall["io"] += time.perf_counter() - c3
        if self.ar_video is not None:
            c4 = time.perf_counter()
            self.ar_video.write(self.ar.compose(pair.left, None, dev.q, t, contact=self._ar_contact(dev)))
            self.wall["ar"] = self.wall.get("ar", 0.0) + time.perf_counter() - c4
        if self.bar is not None:
            self.bar.update(1)

    def _ar_contact(self, dev):
        """Where the device is pressed under its subject's surface, for the AR view (None: no press)."""
        from vishap.ar import Contact

        law = self.st.cycle.step.contact.law
        if law is None:
            return None
        p = np.asarray(dev.p_robot, float) + self.st.mount_offset
        depth = float(law.depth(p))
        return Contact(tuple(float(v) for v in p), depth) if depth > 0.0 else None

    # ------------------------------------------------------------------ deliver (1 kHz)
    def deliver(self, t: float) -> None:
        while self.pending and self.pending[0][0] <= t + 1e-12:
            _, res = self.pending.pop(0)
            self.newest = res

    # ------------------------------------------------------------------ scene (60 Hz)
    def scene(self, t: float) -> None:
        r = self.newest
        if r is None or r["index"] == self.newest_seen:
            return
        self.newest_seen = r["index"]
        c0 = time.perf_counter()
        st = self.st
        _, p_dev = st.cycle.step.read()
        calibrated = not self._fault("calibration_missing", t)
        # the tracker's confidence drops with consecutive misses; vision says when the finger is gone
        rec, inter, p_pad = st.scene_step.step(r["t"], r["found"], r["p_cam"], r["confidence"], p_dev,
                                               calibrated=calibrated, lost=r["lost"])
        self.target = rec
        log_scene_row(self.log, t, rec, inter, p_pad, p_dev, st.mount_offset, 1e3 * (time.perf_counter() - c0))
        self.wall["scene"] += time.perf_counter() - c0

    # ------------------------------------------------------------------ run
    def run(self) -> None:
        from vishap._core.results import progress

        self.t_start = time.perf_counter()
        n_ticks = int(round(self.cfg.frames / self.cfg.camera_hz * self.cfg.servo_hz))
        with progress(total=self.cfg.frames, desc=f"demo {self.cfg.scene}", unit="frame",
                      quiet=not self.progress) as self.bar:
            for _ in range(n_ticks):
                self.sched.step()
        self.wall_total = time.perf_counter() - self.t_start

    def finish(self) -> dict:
        from vishap.apps.summary import write_outputs

        if self.video is not None:
            self.video.close()
        if self.ar_video is not None:
            self.ar_video.close()
        wall = {**self.wall, **self.st.cycle.wall, "total": self.wall_total}
        return write_outputs(self.out, self.log, wall=wall, stats={**self.stats, **self.st.cycle.stats},
                             guard_counts=self.st.guard.counts)


def log_scene_row(log, t, rec, inter, p_pad, p_dev, mount, world_ms) -> None:
    """The scene channel's row (one schema for batch, live and replay)."""
    log.channel("scene").append(
        t=t, t_sample=rec.made_at, seq=rec.seq, finger_robot=p_pad, device_point=p_dev,
        X_d=np.asarray(rec.X_ee, float) + mount, calibrated=rec.calibrated, confidence=rec.confidence,
        armed=rec.armed, subject=rec.subject, depth=np.nan if inter is None else float(inter.depth),
        imminent=rec.imminent, in_contact=rec.in_contact, lost=rec.lost, world_ms=world_ms)


def _stage_ms(timings: dict) -> dict:
    """Vision time per stage (ms; NaN when not run): segmentation and detection of both views, stereo."""
    def total(prefix):
        v = [x for k, x in timings.items() if k.startswith(prefix)]
        return float(sum(v)) if v else float("nan")

    return {"segment_ms": total("segment_"), "detect_ms": total("detect_"), "stereo_ms": total("stereo")}


def _label_at(labels: np.ndarray, uv) -> int:
    if labels is None or not np.all(np.isfinite(uv)):
        return -1
    u, v = int(round(uv[0])), int(round(uv[1]))
    if 0 <= v < labels.shape[0] and 0 <= u < labels.shape[1]:
        return int(labels[v, u])
    return -1


def run_demo(cfg: DemoConfig, out, *, progress: bool = False) -> dict:
    demo = Demo(cfg, out, progress=progress)
    demo.run()
    return demo.finish()
