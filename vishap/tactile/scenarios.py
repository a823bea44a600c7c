"""Synthetic contact-sample scenarios in the object frame (z = height above the surface).

These drive the renderer without the world/robot layers: approaches that touch down (for the
feed-forward onset measurement), near-misses that stop short of the surface, presses, slips and a
stroke across the fabric with a speed sweep. Contact force follows a penalty law F = k·depth
(saturating at ``force_n``); while in contact the reported height is 0.
"""
from __future__ import annotations

import numpy as np

from vishap.tactile.contact import ContactSample

__all__ = ["approach", "near_miss", "stroke", "press", "to_arrays", "from_arrays", "SCENARIOS"]

DT = 1e-3
K_N_PER_M = 400.0


def _samples(t, z, vz, x, vx, force_n, y=None, vy=None):
    y = np.zeros_like(t) if y is None else y
    vy = np.zeros_like(t) if vy is None else vy
    out = []
    for k in range(len(t)):
        depth = -z[k]
        f = min(force_n, K_N_PER_M * depth) if depth > 0 else 0.0
        out.append(ContactSample(float(t[k]), np.array([x[k], y[k], max(z[k], 0.0)]), f,
                                 np.array([vx[k], vy[k], vz[k] if z[k] > 0 else 0.0]), bool(f > 0)))
    return out


def approach(speed_m_s: float = 0.1, *, h0_m: float = 0.006, decel_m_s2: float = 0.0, slide_m_s: float = 0.0,
             hold_s: float = 0.15, force_n: float = 0.6) -> tuple[list[ContactSample], float]:
    """Descend from h0 at ``speed_m_s`` (optionally decelerating) and touch down; returns (samples, t_contact)."""
    t = np.arange(0.0, 0.4, DT)
    v = np.maximum(speed_m_s - decel_m_s2 * t, 0.02)
    z = h0_m - np.concatenate([[0.0], np.cumsum(v[:-1]) * DT])
    tc = float(t[np.argmax(z <= 0)])
    # below the surface the finger keeps pressing in until the force saturates
    t = t[t <= tc + hold_s]
    z, v = z[: len(t)], v[: len(t)]
    x = slide_m_s * np.maximum(t - tc, 0.0)
    vx = np.where(t >= tc, slide_m_s, slide_m_s)
    return _samples(t, z, -v, x, vx, force_n), tc


def near_miss(speed_m_s: float = 0.1, stop_m: float = 0.001, *, h0_m: float = 0.006) -> list[ContactSample]:
    """Descend towards the surface and stop ``stop_m`` above it (minimum-jerk deceleration), then lift."""
    dist = h0_m - stop_m
    dur = 1.875 * dist / speed_m_s  # minimum-jerk peak speed = 1.875 · dist / duration
    t = np.arange(0.0, dur + 0.12, DT)
    s = np.clip(t / dur, 0.0, 1.0)
    z = h0_m - dist * (10 * s**3 - 15 * s**4 + 6 * s**5)
    vz = -dist / dur * (30 * s**2 - 60 * s**3 + 30 * s**4)
    lift = t > dur + 0.06
    z = np.where(lift, stop_m + 0.05 * (t - dur - 0.06), z)
    vz = np.where(lift, 0.05, vz)
    return _samples(t, z, vz, np.zeros_like(t), np.zeros_like(t), 0.6)


def stroke(duration_s: float = 1.5, *, v_max_m_s: float = 0.3, force_n: float = 0.5) -> list[ContactSample]:
    """Touch down, then stroke along +x with the speed rising to ``v_max_m_s`` and back (a sweep)."""
    t = np.arange(0.0, duration_s, DT)
    z = np.full_like(t, -0.01)
    z[t < 0.05] = 0.002 - 0.04 * t[t < 0.05]
    vz = np.where(t < 0.05, -0.04, 0.0)
    u = np.clip((t - 0.15) / max(duration_s - 0.3, 0.05), 0.0, 1.0)
    vx = v_max_m_s * np.sin(np.pi * u) ** 2
    x = np.concatenate([[0.0], np.cumsum(vx[:-1]) * DT]) - 0.05
    return _samples(t, z, vz, x, vx, force_n)


def press(duration_s: float = 0.6, force_n: float = 0.65) -> list[ContactSample]:
    """A still fingertip press (the §3.2 situation)."""
    t = np.arange(0.0, duration_s, DT)
    z = 0.002 - 0.05 * t
    return _samples(t, z, np.full_like(t, -0.05), np.zeros_like(t), np.zeros_like(t), force_n)


SCENARIOS = {"stroke": stroke, "press": press, "approach": lambda: approach(0.1, slide_m_s=0.05)[0],
             "slip": lambda: approach(0.08, slide_m_s=0.25, hold_s=0.3)[0]}


def to_arrays(samples: list[ContactSample]) -> dict[str, np.ndarray]:
    """Column arrays (the NPZ layout read by ``vishap tactile render --input``)."""
    return {
        "t": np.array([s.t for s in samples]),
        "position": np.array([s.position for s in samples]),
        "normal_force_n": np.array([s.normal_force_n for s in samples]),
        "velocity": np.array([s.velocity for s in samples]),
        "in_contact": np.array([s.in_contact for s in samples]),
    }


def from_arrays(d) -> list[ContactSample]:
    """Inverse of :func:`to_arrays`; optional ``pad_position`` / ``contact_radius_m`` columns are used."""
    from vishap._core.check import as_array

    t = as_array(d["t"], (None,), "t")
    n = len(t)
    pos = as_array(d["position"], (n, 3), "position")
    vel = as_array(d["velocity"], (n, 3), "velocity")
    f = as_array(d["normal_force_n"], (n,), "normal_force_n")
    ic = np.asarray(d["in_contact"]).astype(bool).reshape(n)
    pad = as_array(d["pad_position"], (n, 2), "pad_position") if "pad_position" in d else None
    rad = as_array(d["contact_radius_m"], (n, 2), "contact_radius_m") if "contact_radius_m" in d else None
    return [ContactSample(float(t[k]), pos[k], float(f[k]), vel[k], bool(ic[k]),
                          None if pad is None else pad[k], None if rad is None else rad[k]) for k in range(n)]


def from_patch_track(track, *, slide_m_s: float = 0.0) -> list[ContactSample]:
    """Contact samples that carry a sleeve patch track's pad geometry (``sequences.PatchTrack``),
    with the finger sliding along +x at ``slide_m_s`` while the force is on."""
    out = []
    x = 0.0
    for k in range(len(track)):
        f = float(track.force_n[k])
        on = f > 0
        out.append(ContactSample(float(track.t[k]), np.array([x, 0.0, 0.0 if on else 0.001]), f,
                                 np.array([slide_m_s if on else 0.0, 0.0, 0.0]), on,
                                 pad_position=track.centre_m[k], contact_radius_m=track.radius_m[k]))
        x += (slide_m_s if on else 0.0) * DT
    return out
