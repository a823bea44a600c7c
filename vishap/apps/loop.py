"""The batch demo: the whole system in one closed loop on a simulated clock (issue 9 part 2).

Per base tick (1 ms) the :class:`~vishap.runtime.MultiRateScheduler` runs, in this order:

``camera``  (30 Hz)  render the stereo pair *after* the physics reached the frame's time, showing the
                     scripted finger and the device where the MuJoCo plant is; run vision on it; the
                     estimate becomes available ``vision_latency_s`` later (VisHap §2.1);
``deliver`` (1 kHz)  hand due vision results to the scene (a latest-value hand-over);
``scene``   (60 Hz)  registration (camera → robot, Eq. 3) and :meth:`World.update` (§2.2) on the
                     newest estimate → the device target ``X_d``;
``servo``   (1 kHz)  the target guard (hold / retreat on bad input) → finger-pad contact → the
                     world's force law → :class:`ServoLoop` tick (PD + gravity comp., Eq. 4–8),
                     which steps the MuJoCo plant;
``tactile`` (1 kHz)  contact sample → tactile renderer (HAPTEX §II-C, 40 Hz pin update inside).

Ground truth (the scripted finger) drives only what is physically the user's: the rendered hand
and the pad's contact with the passive object. Everything the system knows about the finger
comes through the rendered pixels and the vision pipeline.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from vishap._core.pose import invert, transform_points
from vishap.apps.config import DemoConfig
from vishap.apps.log import SignalLog, write_frame_png
from vishap.apps.script import script_for
from vishap.apps.stages import need, tactile_row

__all__ = ["Demo", "run_demo"]

GUARD_CODES = {"track": 0, "hold": 1, "retreat": 2, "idle": 3}


class Demo:
    """One batch run; :meth:`run` then :meth:`finish` (writes every output)."""

    def __init__(self, cfg: DemoConfig, out, *, progress: bool = False):
        from vishap.apps import assemble

        self.cfg = cfg
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.progress = progress
        self.st = assemble.build(cfg, self.out)
        st = self.st
        self.script = script_for(cfg.scene, hidden_s=cfg.background_frames / cfg.camera_hz)
        self.n = np.asarray(st.scene_object.normal, float)
        self.log = SignalLog(assemble.meta(cfg, st))
        self.frame_index = 0
        self.pending: list[tuple[float, dict]] = []   # (available_at, vision result)
        self.newest: dict | None = None               # vision → scene mailbox
        self.newest_seen = -1
        self.target = {"X_d": np.full(3, np.nan), "made_at": -math.inf, "confidence": 0.0, "calibrated": st.T_est is not None}
        self.armed = False          # the guard starts once the first finger estimate (or a calibration fault) arrives
        self.inter = None           # the world's newest Interaction
        self.lam_state = None       # object gain Λ currently set in the controller (None: identity)
        self.last_key = None
        self.last_action = "idle"
        self.retreat_key = None
        self.contact = None
        self.video = None
        if cfg.video:
            from vishap.apps.overlay import VideoWriter

            self.video = VideoWriter(self.out / "demo.mp4", cfg.camera_hz)
        self.wall = {"render": 0.0, "vision": 0.0, "servo": 0.0, "tactile": 0.0, "scene": 0.0, "io": 0.0}
        self.stats = {"frames_dropped": 0, "force_over_limit": 0, "nonfinite_commands": 0, "reaction_misses": 0}

        runtime = need("vishap.runtime", "runtime")
        self.sched = runtime.MultiRateScheduler(cfg.servo_hz)
        self.sched.add("camera", cfg.camera_hz, self.camera)
        self.sched.add("deliver", cfg.servo_hz, self.deliver)
        self.sched.add("scene", cfg.scene_hz, self.scene)
        self.sched.add("servo", cfg.servo_hz, self.servo)
        self.sched.add("tactile", cfg.tactile_hz, self.tactile)

    # ------------------------------------------------------------------ helpers
    def _fault(self, kind: str, t: float) -> bool:
        return self.cfg.fault_active(kind, t)

    def _device_point(self, p_ee) -> np.ndarray:
        return np.asarray(p_ee, float) + self.st.mount_offset

    def _finger(self, t: float):
        pad, v = self.script.pad(t)
        return pad, v, pad + self.st.tip_radius_m * self.n

    # ------------------------------------------------------------------ camera (30 Hz)
    def camera(self, t: float) -> None:
        k = self.frame_index
        if k >= self.cfg.frames:
            return
        self.frame_index += 1
        st = self.st
        dev = st.plant.read()
        _, _, tip = self._finger(t)
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
        row = {"t": t, "index": k, "dropped": dropped, "found": False, "p_cam": np.full(3, np.nan),
               "uv_left": np.full(2, np.nan), "uv_right": np.full(2, np.nan), "confidence": 0.0,
               "vision_ms": np.nan, "available_at": np.nan, "tip_cam_true": tip_cam, "tip_robot_true": tip,
               "tip_visible": tip_vis, "hand_visible": visible, "render_ms": 1e3 * (c1 - c0),
               "device_q": dev.q, "device_ee": dev.p_robot, **_stage_ms({})}
        est = None
        if dropped:
            self.stats["frames_dropped"] += 1
            st.guard.count("frame_dropped")
        else:
            c2 = time.perf_counter()
            est = st.vision.process(st.StereoFrame(k, t, pair.left, pair.right))
            self.wall["vision"] += time.perf_counter() - c2
            res = st.vision_result(est)
            if self._fault("nan", t) and res["found"]:
                res["p_cam"] = np.full(3, np.nan)
            available = t + self.cfg.vision_latency_s
            for f in self.cfg.faults:
                if f.kind == "vision_stalled" and f.active(t):
                    available = max(available, f.t_end + self.cfg.vision_latency_s)
            self.pending.append((available, {"t": t, "index": k, **res}))
            row.update(found=res["found"], p_cam=res["p_cam"], uv_left=res["uv_left"], uv_right=res["uv_right"],
                       confidence=res["confidence"], vision_ms=res["vision_ms"], available_at=available,
                       **_stage_ms(est.timings))
        self.log.channel("vision").append(**row)
        if self.video is not None:
            c3 = time.perf_counter()
            f = 0.0 if self.contact is None else float(np.linalg.norm(self.contact[0]))
            extra = [f"device: {self.last_action}   contact force {f:4.2f} N"]
            self.video.write(st.overlay(pair, row, dev, self.target, t, extra))
            self.wall["io"] += time.perf_counter() - c3
        if self.progress and (k % 10 == 0 or k == self.cfg.frames - 1):
            print(f"\rdemo {self.cfg.scene}: frame {k + 1}/{self.cfg.frames}", end="", file=sys.stderr, flush=True)

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
        calibrated = st.T_est is not None and not self._fault("calibration_missing", t)
        X_d = np.full(3, np.nan)
        p_pad = np.full(3, np.nan)
        inter = None
        p_dev = self._device_point(st.plant.read().p_robot)
        if calibrated:
            if r["found"] and np.all(np.isfinite(r["p_cam"])):
                p_pad = transform_points(st.T_est, r["p_cam"]) - st.tip_radius_m * self.n
                inter = st.world.update(r["t"], p_pad, p_dev)
            elif not r["found"] and self.armed:
                inter = st.world.update(r["t"], None, p_dev)
            if inter is not None:
                X_d = np.asarray(inter.X_d, float) - st.mount_offset
                self.inter = inter
        if not self.armed and (not calibrated or r["found"]):
            self.armed = True
        confidence = float(r["confidence"])  # the tracker's: drops with consecutive misses
        self.target = {"X_d": X_d, "made_at": r["t"], "confidence": confidence, "calibrated": calibrated}
        self.log.channel("scene").append(
            t=t, t_sample=r["t"], finger_robot=p_pad, X_d=X_d + st.mount_offset, calibrated=calibrated,
            subject=-1 if inter is None or inter.object_name is None else st.object_index(inter.object_name),
            depth=np.nan if inter is None else float(inter.depth),
            imminent=bool(inter is not None and inter.imminent),
            in_contact=bool(inter is not None and inter.in_contact), world_ms=1e3 * (time.perf_counter() - c0))
        self.wall["scene"] += time.perf_counter() - c0

    # ------------------------------------------------------------------ servo (1 kHz)
    def servo(self, t: float) -> None:
        c0 = time.perf_counter()
        st = self.st
        tg = self.target
        if self.armed:
            dec = st.guard.decide(t, tg["X_d"], tg["made_at"], tg["confidence"], tg["calibrated"])
            action, X_ee = dec.action, dec.X_d
            bad = (not tg["calibrated"] or not np.all(np.isfinite(tg["X_d"]))
                   or t - tg["made_at"] > st.guard.stale_after_s or tg["confidence"] < st.guard.min_confidence)
            if bad and action == "track":
                self.stats["reaction_misses"] += 1
        else:  # no finger seen yet: the servo holds the arm where it is
            action, X_ee = "idle", None
        dev = st.plant.read()
        p_dev = self._device_point(dev.p_robot)
        pad, v_pad, _ = self._finger(t)
        F_on_dev = st.pad_force(pad, v_pad, p_dev, dev.v_robot)
        st.plant.apply_tip_force(F_on_dev)
        # the subject's law renders contact while the device is pushed under its surface (Eq. 8-9);
        # a retreating device renders nothing
        world, ctrl = st.world, st.controller
        F_law, lam, R = world.contact_render(p_dev, dev.v_robot, self.inter if action in ("track", "hold") else None)
        if lam != self.lam_state:
            ctrl.set_lambda(lam, None if lam is None else R)
            if lam is None and world.law is not None:
                world.law.reset()
            self.lam_state = lam
        if action == "track":
            key = tg["made_at"]
        elif action == "retreat":
            if self.last_action != "retreat":
                self.retreat_key = t
            key = self.retreat_key
        else:
            key = self.last_key
        self.last_key, self.last_action = key, action
        st.servo.tick(t, None if key is None else X_ee, F_law, t_sample=key)
        F_cmd = np.array(ctrl.F_cmd, float)
        F_pd = np.array(ctrl.F_pd, float)
        if not np.all(np.isfinite(F_cmd)):
            self.stats["nonfinite_commands"] += 1
        if float(np.linalg.norm(F_cmd)) > st.force_limit_n * (1 + 1e-6):
            self.stats["force_over_limit"] += 1
        dt_wall = time.perf_counter() - c0
        self.wall["servo"] += dt_wall
        obj = st.scene_object
        F_on_finger = -F_on_dev
        self.contact = (F_on_finger, pad, v_pad)
        X_log = np.full(3, np.nan) if X_ee is None else X_ee + st.mount_offset
        self.log.channel("servo").append(
            t=t, q=dev.q, p_ee=dev.p_robot, device_point=p_dev, v_device=dev.v_robot,
            X_d=X_log, guard=GUARD_CODES[action], F_cmd=F_cmd, F_pd=F_pd,
            F_law=np.zeros(3) if F_law is None else np.asarray(F_law, float), law_active=F_law is not None,
            F_contact=F_on_finger, in_contact=bool(np.any(F_on_dev)),
            saturated=bool(ctrl.saturated), heat_n2=float(ctrl.heat),
            finger_point=pad, finger_velocity=v_pad, finger_depth=-float(obj.height(pad)), device_depth=-float(obj.height(p_dev)),
            tick_us=1e6 * dt_wall)

    # ------------------------------------------------------------------ tactile (1 kHz)
    def tactile(self, t: float) -> None:
        if self.contact is None or self.st.tactile is None:
            return
        c0 = time.perf_counter()
        F_on_finger, pad, v_pad = self.contact
        st = self.st
        sample = st.contact_sample(t, pad, v_pad, F_on_finger, self.script.finger_dir)
        out = st.tactile.step(sample)
        row = {"t": t, "normal_force": float(sample.normal_force_n), "in_contact": bool(sample.in_contact),
               "position": sample.position, "velocity": sample.velocity, "state": st.tactile_state(out)}
        row.update(tactile_row(out))
        self.log.channel("tactile").append(**row)
        self.wall["tactile"] += time.perf_counter() - c0

    # ------------------------------------------------------------------ run
    def run(self) -> None:
        self.t_start = time.perf_counter()
        n_ticks = int(round(self.cfg.frames / self.cfg.camera_hz * self.cfg.servo_hz))
        for _ in range(n_ticks):
            self.sched.step()
        self.wall_total = time.perf_counter() - self.t_start
        if self.progress:
            print(file=sys.stderr)

    def finish(self) -> dict:
        from vishap.apps.summary import write_outputs

        if self.video is not None:
            self.video.close()
        return write_outputs(self)


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
