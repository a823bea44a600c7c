"""Tracking of the servo loop: step and ramp responses, and moving targets through the X_d gap.

VisHap §2.3 tunes Kp, Kv "to make the system critically or over damped" and low-pass filters the
error because X_d arrives at vision rate. :func:`step_response` and :func:`ramp_response` run the
closed loop in MuJoCo and measure settling time, overshoot and steady-state error;
:func:`moving_target` feeds a smooth finger path, sampled at a vision rate (optionally with noise),
through a gap policy of :class:`~vishap.robot.servo.TargetShaper` and measures the error to the
true path and the roughness of the commanded force.
"""
from __future__ import annotations

import math

import numpy as np

from vishap._core.errors import ConfigError

from vishap.robot.controller import Controller, Gains
from vishap.robot.kinematics import ik
from vishap.robot.plant import MujocoPlant
from vishap.robot.servo import ServoLoop
from vishap.world.scene import demo_passive_object

__all__ = ["CENTRE", "step_response", "ramp_response", "moving_target", "step_metrics", "finger_path", "band_rms",
           "hold_and_approach"]

CENTRE = np.array([0.200, 0.0, -0.120])


def _loop(gains: Gains, *, p0=CENTRE, policy="hold", substeps=1, gravity_comp=True):
    plant = MujocoPlant(passive_object=demo_passive_object(), q0=ik(np.asarray(p0)), substeps=substeps)
    ctrl = Controller(plant.params, gains, limits=plant.limits)
    if not gravity_comp:
        from dataclasses import replace

        ctrl.set_gravity(replace(plant.params, m_a=0.0, m_c=0.0, m_be=0.0, m_df=0.0, m_tip=0.0))
    return plant, ctrl, ServoLoop(plant, ctrl, policy=policy)


def step_metrics(t, y, t0: float, amplitude: float, *, band: float = 0.02) -> dict:
    """Settling time (to within ``band``·amplitude), overshoot (%), steady-state error (m), 10–90 % rise time."""
    t = np.asarray(t)
    y = np.asarray(y)
    after = t >= t0
    ta, ya = t[after] - t0, y[after]
    tol = band * abs(amplitude)
    outside = np.nonzero(np.abs(ya - amplitude) > tol)[0]
    settle = float(ta[outside[-1] + 1]) if outside.size and outside[-1] + 1 < ta.size else (0.0 if not outside.size else math.inf)
    over = float(max(0.0, (np.max(ya * np.sign(amplitude)) - abs(amplitude)) / abs(amplitude) * 100.0))
    tail = ya[ta >= ta[-1] - 0.1]
    sse = float(abs(np.mean(tail) - amplitude))
    i10 = np.argmax(ya * np.sign(amplitude) >= 0.1 * abs(amplitude))
    i90 = np.argmax(ya * np.sign(amplitude) >= 0.9 * abs(amplitude))
    rise = float(ta[i90] - ta[i10]) if ya[i90] * np.sign(amplitude) >= 0.9 * abs(amplitude) else math.inf
    return {"settling_time_s": settle, "overshoot_pct": over, "steady_state_error_m": sse, "rise_time_s": rise}


def step_response(gains: Gains, direction, amplitude: float = 0.02, *, duration_s: float = 1.0, t_step: float = 0.1, **kw) -> dict:
    """Step of ``amplitude`` (m) along ``direction`` at ``t_step``; returns the trace and :func:`step_metrics`."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    p0 = CENTRE - 0.5 * amplitude * d
    plant, ctrl, servo = _loop(gains, p0=p0, **kw)
    n = int(round(duration_s / plant.dt))
    t = np.arange(n) * plant.dt
    y = np.empty(n)
    for i in range(n):
        X = p0 + (amplitude * d if t[i] >= t_step else 0.0)
        servo.tick(t[i], X)
        y[i] = float(np.dot(np.asarray(ctrl.p) - p0, d))
    return {"t": t, "y": y, **step_metrics(t, y, t_step, amplitude)}


def ramp_response(gains: Gains, direction, speed_m_s: float = 0.05, *, move_s: float = 0.6, duration_s: float = 1.4, t0: float = 0.1, **kw) -> dict:
    """Ramp at ``speed_m_s`` along ``direction`` for ``move_s``; following error during the ramp, settling after."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    span = speed_m_s * move_s
    p0 = CENTRE - 0.5 * span * d
    plant, ctrl, servo = _loop(gains, p0=p0, **kw)
    n = int(round(duration_s / plant.dt))
    t = np.arange(n) * plant.dt
    y = np.empty(n)
    ref = np.clip((t - t0) * speed_m_s, 0.0, span)
    for i in range(n):
        servo.tick(t[i], p0 + ref[i] * d)
        y[i] = float(np.dot(np.asarray(ctrl.p) - p0, d))
    moving = (t > t0 + 0.3 * move_s) & (t < t0 + move_s)
    m = step_metrics(t, y, t0 + move_s, span)
    return {
        "t": t,
        "y": y,
        "ref": ref,
        "following_error_m": float(np.mean(ref[moving] - y[moving])),
        "settling_after_stop_s": m["settling_time_s"],
        "overshoot_pct": m["overshoot_pct"],
        "steady_state_error_m": m["steady_state_error_m"],
    }


def finger_path(t):
    """A smooth finger path inside the box (robot frame, m): sums of sines, peak speed ≈ 0.15 m/s."""
    t = np.asarray(t, dtype=np.float64)
    x = 0.200 + 0.04 * np.sin(2 * np.pi * 0.45 * t) + 0.01 * np.sin(2 * np.pi * 1.3 * t + 0.4)
    y = 0.035 * np.sin(2 * np.pi * 0.31 * t + 1.0)
    z = -0.120 + 0.03 * np.sin(2 * np.pi * 0.6 * t + 2.0)
    return np.stack([x, y, z], axis=-1)


def moving_target(gains: Gains, policy: str, rate_hz: float, *, duration_s: float = 3.0, noise_m: float = 0.0,
                  latency_s: float = 0.0, seed: int = 0, substeps: int = 1) -> dict:
    """Track :func:`finger_path` sampled at ``rate_hz`` (+ Gaussian noise, + latency) through ``policy``.

    Returns RMS / 95th-percentile error to the true path after the first 0.5 s, and the RMS change
    of the commanded force per tick (N), a measure of how rough the rendered motion feels.
    """
    rng = np.random.default_rng(seed)
    plant, ctrl, servo = _loop(gains, p0=finger_path(0.0), policy=policy, substeps=substeps)
    n = int(round(duration_s / plant.dt))
    t = np.arange(n) * plant.dt
    truth = finger_path(t)
    period = 1.0 / rate_hz
    p = np.empty((n, 3))
    F = np.empty((n, 3))
    ts_last = None
    X = truth[0]
    for i in range(n):
        # the latest frame available now was captured latency_s earlier; samples carry capture times
        ts = math.floor((t[i] - latency_s) / period + 1e-9) * period
        if ts != ts_last:
            ts_last = ts
            X = finger_path(ts) + (rng.normal(0.0, noise_m, 3) if noise_m > 0 else 0.0)
        servo.tick(t[i], X, t_sample=ts)
        p[i] = ctrl.p
        F[i] = ctrl.F_cmd
    k = t >= 0.5
    err = np.linalg.norm(p[k] - truth[k], axis=1)
    dF = np.linalg.norm(np.diff(F[k], axis=0), axis=1)
    return {
        "policy": policy,
        "rate_hz": rate_hz,
        "noise_m": noise_m,
        "latency_s": latency_s,
        "rms_error_m": float(np.sqrt(np.mean(err**2))),
        "p95_error_m": float(np.percentile(err, 95)),
        "force_roughness_n": float(np.sqrt(np.mean(dF**2))),
        "t": t,
        "p": p,
        "truth": truth,
    }


def band_rms(x, fs: float, lo_hz: float = 0.0, hi_hz: float = math.inf) -> float:
    """RMS (over all columns together) of the part of ``x`` between ``lo_hz`` and ``hi_hz`` (its mean
    removed), from the FFT of the record mirrored onto itself: Parseval on the one-sided spectrum.

    The FFT takes what it is given as one period of a periodic signal. A record cut out of a longer
    trace (an approach whose force goes from −0.6 to +0.7 N in 156 ms) would carry the jump between
    its ends as a sawtooth whose 1/f harmonics fill every band: 0.14 N "above 30 Hz" in such a piece
    holding 0.035 N of 55 Hz buzz. The record followed by its reverse (the even extension, as the
    DCT takes it) joins without a jump; its RMS is the record's, and what is left of the ends is a
    kink whose harmonics fall as 1/f² (that piece reads 0.0353 N, its buzz alone 0.0353 N)."""
    x = np.asarray(x, dtype=np.float64)
    if len(x) < 4:
        return 0.0
    x = x.reshape(len(x), -1) - np.mean(x, axis=0).reshape(1, -1)
    x = np.concatenate([x, x[::-1]])
    X = np.fft.rfft(x, axis=0)
    f = np.fft.rfftfreq(len(x), 1.0 / fs)
    w = np.where((f > lo_hz) & (f <= hi_hz), 2.0, 0.0)
    w[0] = 0.0
    w[-1] = np.where(w[-1] > 0, 1.0, 0.0)  # the extension has an even length: the last bin is Nyquist
    return float(np.sqrt(np.sum(w[:, None] * np.abs(X) ** 2) / len(x) ** 2))


def hold_and_approach(gains: Gains, scenario: str, *, seconds: float = 2.0, vision_hz: float = 30.0,
                      speed_m_s: float = 0.1, substeps: int = 10, settle_s: float = 0.6) -> dict:
    """The servo as the demos run it (encoder, ``substeps``, ``interpolate`` policy) holding still
    (``scenario="hold"``) or following a target that moves at ``speed_m_s`` along x, sampled at
    ``vision_hz`` (``"approach"``). Returns the commanded PD force ``F`` (N, per tick), the true tip
    position ``p`` (m, MuJoCo's, not the encoder's) and the tick times after ``settle_s``."""
    if scenario not in ("hold", "approach"):
        raise ValueError(f"scenario: expected 'hold' or 'approach', got {scenario!r}")
    if not seconds > settle_s + 0.1:
        raise ConfigError(f"seconds = {seconds!r}: the run must outlast the {settle_s} s settling time by at least "
                          "0.1 s to leave a signal to measure", field="seconds")
    p0 = CENTRE
    plant = MujocoPlant(passive_object=demo_passive_object(), q0=ik(p0), substeps=substeps, sensor="encoder")
    ctrl = Controller(plant.params, gains, limits=plant.limits)
    servo = ServoLoop(plant, ctrl, policy="interpolate")
    n = int(round(seconds * plant.params.servo_rate_hz))
    F = np.empty((n, 3))
    P = np.empty((n, 3))
    for k in range(n):
        t = k * plant.dt
        ts = math.floor(t * vision_hz + 1e-9) / vision_hz
        X = p0 if scenario == "hold" else p0 + np.array([speed_m_s * min(ts, 1.0) - 0.5 * speed_m_s, 0.0, 0.0])
        servo.tick(t, X, t_sample=ts)
        F[k] = ctrl.F_pd
        P[k] = plant.tip_position()
    i0 = int(settle_s * plant.params.servo_rate_hz)
    return {"t": np.arange(i0, n) * plant.dt, "F": F[i0:], "p": P[i0:]}
