"""What runs at 1 kHz in every mode: the finger's contact with the device, the servo step, the sleeve.

:class:`ServoCycle` is the same object in the batch demo (called by the simulated clock's
scheduler) and in live mode (built inside the real-time servo process and stepped by its timer):

``servo(t, record)``  the user's finger acts on the simulated device (a :class:`Finger` pressing the
                      passive object; absent for a real device, where a real finger does), then
                      :class:`~vishap.runtime.core.ServoStep` (guard → law and Λ → controller → device);
``tactile(t)``        the sleeve's contact sample → :class:`~vishap.tactile.renderer.TactileRenderer`.

Both write their rows into the run's ``servo`` and ``tactile`` channels, so demo and live logs
share one schema. What the tactile layer is given follows what the system knows: the sleeve's own
sensor (worn on the finger) gives the normal force, the contact flag and the finger's pitch; the
finger's position and velocity come from the device while touching (the finger drags it) and from
the tracked finger (the world's prediction in the target record) otherwise — never from the
simulated finger.
"""
from __future__ import annotations

import math
import time

import numpy as np

from vishap.runtime.core import GUARD_CODES, ServoStep, TargetRecord
from vishap.tactile.contact import ContactSample

__all__ = ["ServoCycle", "Finger", "ScriptedFinger", "TrackedFinger", "RecordedFinger", "pad_force", "tactile_row"]

STATE_CODES = {"none": 0, "concentrated": 1, "distributed": 2, "slip": 3}


class Finger:
    """The user's finger as the simulated device feels it: ``pad(t, record) -> (pad point, velocity)``
    (robot frame) and ``finger_dir`` (its pointing direction, sensed by the sleeve)."""

    finger_dir = (-0.766, 0.0, -0.643)

    def pad(self, t: float, rec: TargetRecord):
        raise NotImplementedError


class ScriptedFinger(Finger):
    """The demo's scripted finger (:mod:`vishap.apps.script`)."""

    def __init__(self, script):
        self.script = script
        self.finger_dir = tuple(script.finger_dir)

    def pad(self, t, rec):
        return self.script.pad(t)


class RecordedFinger(Finger):
    """A recording's ground-truth finger (``gt.npz`` of a ``vishap synth`` folder): the pad point
    interpolated between frames (cubic Hermite on the recorded positions and velocities); the
    recording's time ``t_source = t + offset`` where ``offset`` is set when its first frame is grabbed."""

    def __init__(self, t, pad_robot, v_robot, finger_dir=None):
        self.t = np.asarray(t, float)
        self.p = np.asarray(pad_robot, float)
        self.v = np.asarray(v_robot, float)
        if finger_dir is not None:
            self.finger_dir = tuple(float(x) for x in finger_dir)
        self.offset = None

    def pad(self, t, rec):
        if self.offset is None:
            return np.full(3, np.nan), np.zeros(3)
        ts = t + self.offset
        T = self.t
        if ts <= T[0]:
            return self.p[0].copy(), np.zeros(3)
        if ts >= T[-1]:
            return self.p[-1].copy(), np.zeros(3)
        k = int(np.searchsorted(T, ts, side="right") - 1)
        h = T[k + 1] - T[k]
        s = (ts - T[k]) / h
        p0, p1, m0, m1 = self.p[k], self.p[k + 1], self.v[k] * h, self.v[k + 1] * h
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
        return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1, (d00 * p0 + d10 * m0 + d01 * p1 + d11 * m1) / h


class TrackedFinger(Finger):
    """Without ground truth the simulated device is pressed by the tracked finger: the world's
    prediction carried in the target record, extrapolated to the servo's time."""

    def pad(self, t, rec):
        if not math.isfinite(rec.finger_t):
            return np.full(3, np.nan), np.zeros(3)
        return rec.finger_at(t)


def pad_force(obj, half_size_m: float):
    """The finger pad's force on the passive object (compliant pad with slip; :class:`FingerPad`)."""
    from vishap.world.closed_loop import FingerPad

    pad = FingerPad()
    n = np.asarray(obj.normal, float)
    return lambda p_f, v_f, p_dev, v_dev: pad.force_on_device(p_f, v_f, p_dev, v_dev, n, half_size_m)


def _or_zero(F) -> np.ndarray:
    """A force that may be absent (None) as the logged vector (zero when absent)."""
    return np.zeros(3) if F is None else np.asarray(F, float)


def tactile_row(out) -> dict[str, np.ndarray]:
    """Flatten the tactile renderer's per-tick output (a dataclass) into named numeric arrays."""
    row = {}
    for k in out.__dataclass_fields__:
        v = getattr(out, k)
        if isinstance(v, str) or isinstance(getattr(v, "value", None), str):  # an Enum state
            continue
        try:
            a = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            continue
        row[k] = a.astype(np.float32) if a.size > 1 else a
    return row


def tactile_state(out) -> int:
    s = getattr(out, "state", None)
    s = getattr(s, "value", s)
    return STATE_CODES.get(str(s), 0) if s is not None else 0


def contact_sample(obj, t, p_device, v_device, rec: TargetRecord, F_on_finger, finger_dir_robot):
    """The sleeve's contact sample in the object frame, from what the system knows (module docstring)."""
    n = np.asarray(obj.normal, float)
    fn = float(np.asarray(F_on_finger, float) @ n)
    touching = fn > 0.0
    if touching:
        p, v = np.asarray(p_device, float), np.asarray(v_device, float)
    else:
        p, v = rec.finger_at(t)
    d_obj = None if finger_dir_robot is None else obj.R.T @ np.asarray(finger_dir_robot, float)
    return ContactSample(t=t, position=obj.local(p), normal_force_n=max(0.0, fn), velocity=obj.R.T @ v,
                         in_contact=touching, finger_dir=d_obj)


class ServoCycle:
    """Finger → servo step → log; sleeve → tactile renderer → log (see the module docstring).

    ``finger`` is None for a real device. ``log`` is the run's :class:`~vishap.apps.log.SignalLog`.
    """

    def __init__(self, step: ServoStep, *, scene_object, log, finger: Finger | None = None,
                 half_size_m: float = 0.02, tactile=None):
        self.step = step
        self.obj = scene_object
        self.n = np.asarray(scene_object.normal, float)
        self.finger = finger
        self.pad_force = pad_force(scene_object, half_size_m) if finger is not None else None
        self._true_tip = getattr(step.device, "true_tip_state", None)  # a simulated device's own state
        self.tactile_renderer = tactile
        self.log = log
        self.stats = {"force_over_limit": 0, "nonfinite_commands": 0}
        self.force_limit_n = float(step.device.limits.peak_force_n)
        self.last = None  # (F_on_finger, p_device, v_device, record) of the latest servo tick
        self.last_q = np.full(3, np.nan)  # the device's joint angles at the latest servo tick (rad)
        self.wall = {"servo": 0.0, "tactile": 0.0}

    def servo(self, t: float, rec: TargetRecord) -> None:
        c0 = time.perf_counter()
        step = self.step
        dev, p_dev = step.read()
        if self.finger is not None:
            pad, v_pad = self.finger.pad(t, rec)
            # the finger touches the device where it is, not where its encoders say it is
            p_phys, v_phys = (self._true_tip() if self._true_tip is not None else (dev.p_robot, dev.v_robot))
            F_on_dev = (self.pad_force(pad, v_pad, p_phys + step.mount, v_phys) if np.all(np.isfinite(pad))
                        else np.zeros(3))
            step.device.apply_tip_force(F_on_dev)
        else:
            pad, v_pad, F_on_dev = np.full(3, np.nan), np.full(3, np.nan), np.zeros(3)
        tk = step.tick(t, rec, dev)
        ctrl = step.controller
        F_cmd = np.array(ctrl.F_cmd, float)
        if not np.all(np.isfinite(F_cmd)):
            self.stats["nonfinite_commands"] += 1
        if float(np.linalg.norm(F_cmd)) > self.force_limit_n * (1 + 1e-6):
            self.stats["force_over_limit"] += 1
        dt_wall = time.perf_counter() - c0
        self.wall["servo"] += dt_wall
        F_on_finger = -F_on_dev
        self.last = (F_on_finger, p_dev, dev.v_robot, rec)
        self.last_q = dev.q
        obj = self.obj
        self.log.channel("servo").append(
            t=t, q=dev.q, p_ee=dev.p_robot, device_point=p_dev, v_device=dev.v_robot,
            X_d=np.full(3, np.nan) if tk.X_ee is None else tk.X_ee + step.mount, guard=GUARD_CODES[tk.action],
            record_seq=rec.seq, F_cmd=F_cmd, F_pd=np.array(ctrl.F_pd, float),
            F_law=_or_zero(tk.F_law), law_active=tk.F_law is not None,
            F_hold=_or_zero(step.contact.F_hold),
            lambda_state=tk.lambda_state, force_scale=tk.force_scale, finger_m=tk.finger_m, pressed=tk.pressed,
            F_contact=F_on_finger, in_contact=bool(np.any(F_on_dev)), saturated=bool(ctrl.saturated),
            heat_n2=float(ctrl.heat), finger_point=pad, finger_velocity=v_pad,
            finger_depth=-float(obj.height(pad)), device_depth=-float(obj.height(p_dev)), tick_us=1e6 * dt_wall)

    def tactile(self, t: float) -> None:
        if self.last is None or self.tactile_renderer is None:
            return
        c0 = time.perf_counter()
        F_on_finger, p_dev, v_dev, rec = self.last
        finger_dir = None if self.finger is None else self.finger.finger_dir
        sample = contact_sample(self.obj, t, p_dev, v_dev, rec, F_on_finger, finger_dir)
        out = self.tactile_renderer.step(sample)
        self.log.channel("tactile").append(
            t=t, normal_force=float(sample.normal_force_n), in_contact=bool(sample.in_contact),
            position=sample.position, velocity=sample.velocity, state=tactile_state(out), **tactile_row(out))
        self.wall["tactile"] += time.perf_counter() - c0
