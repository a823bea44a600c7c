"""Synthetic contact sequences on the sleeve array (PHSM §3.2–3.4 worked examples and labelled sets).

Every sequence is a list of patch descriptions sampled at 1 kHz — (t, centre (2,), semi-axes (2,),
force) in the sleeve frame — that :func:`frames` turns into noisy :class:`SensorFrame` readings.
The three worked examples reproduce the paper's numbers: pressing at x = 3.5 cm with 0.65 N
(§3.2); the patch growing from 0.5 to 1.6 cm² while the force falls from 0.65 to 0.48 N and stays
stable for more than 250 ms (§3.3); the centroid moving from 6.5 to 3.9 cm in 0.12 s (§3.4).
:func:`labelled_sequence` draws randomised presses, pad strokes and edge sweeps with noise, labelled
by the physical action that generated them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap.tactile.classifier import ContactState
from vishap.tactile.sensor import SensorArray, SensorFrame

__all__ = ["PatchTrack", "worked_example", "WORKED_EXAMPLES", "labelled_sequence", "frames", "SETTLE_S"]

DT = 1e-3
WORKED_EXAMPLES = ("concentrated", "distributed", "slip")
#: decision time each rule needs before a label is scored (velocity window + hold; 250 ms stability)
SETTLE_S = {ContactState.CONCENTRATED: 0.03, ContactState.DISTRIBUTED: 0.30, ContactState.SLIP: 0.04}


@dataclass
class PatchTrack:
    """A contact patch over time: t (N,), centre_m (N, 2), radius_m (N, 2), force_n (N,)."""

    t: np.ndarray
    centre_m: np.ndarray
    radius_m: np.ndarray
    force_n: np.ndarray
    label: ContactState = ContactState.NONE
    label_from_s: float = 0.0  # time from which the label is scored

    def __len__(self) -> int:
        return len(self.t)


def _radius_for_area(area_m2: float, aspect: float = 1.0) -> np.ndarray:
    """Semi-axes (a_x, a_y) of an ellipse with the given area and a_x/a_y = aspect."""
    ay = np.sqrt(area_m2 / (np.pi * aspect))
    return np.array([aspect * ay, ay])


def _lerp(a, b, s):
    s = np.clip(s, 0.0, 1.0)[:, None] if np.ndim(s) else np.clip(s, 0.0, 1.0)
    return np.asarray(a) * (1 - s) + np.asarray(b) * s


def _smooth(s):
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3 - 2 * s)


def worked_example(name: str) -> PatchTrack:
    """The paper's worked example ``name`` ∈ {concentrated, distributed, slip} as a patch track.

    The classification instant is the last sample (t = 1.2 s for §3.2, as in the paper).
    """
    if name == "concentrated":  # §3.2: fingertip press near x = mu1 = 3.5 cm, 0.65 N at t = 1.2 s
        t = np.arange(1.0, 1.2 + DT / 2, DT)
        s = _smooth((t - 1.0) / 0.08)
        force = 0.65 * s
        centre = np.tile([0.035, 0.0], (len(t), 1))
        r = _radius_for_area(0.5e-4)
        radius = np.outer(np.maximum(s, 0.05) ** (1 / 3), r)
        return PatchTrack(t, centre, radius, force, ContactState.CONCENTRATED, 1.2)
    if name == "distributed":  # §3.3: 0.5 -> 1.6 cm^2, 0.65 -> 0.48 N, stable > 250 ms, centroid -> mu2
        t = np.arange(0.0, 0.60 + DT / 2, DT)
        s = _smooth((t - 0.05) / 0.20)
        area = 0.5e-4 + (1.6e-4 - 0.5e-4) * s
        aspect = 1.0 + 1.2 * s  # the pad contact elongates along the finger
        radius = np.array([_radius_for_area(a, k) for a, k in zip(area, aspect)])
        centre = _lerp([0.035, 0.0], [0.050, 0.0], s)
        force = 0.65 + (0.48 - 0.65) * s + 0.004 * np.sin(2 * np.pi * 3.0 * t)
        return PatchTrack(t, centre, radius, force, ContactState.DISTRIBUTED, t[-1])
    if name == "slip":  # §3.4: lateral edge sweeps mu = 6.5 -> 3.9 cm within 0.12 s (~22 cm/s), obliquely
        t = np.arange(0.0, 0.16 + DT / 2, DT)
        s = np.clip((t - 0.04) / 0.12, 0.0, 1.0)
        centre = _lerp([0.065, 0.003], [0.039, -0.003], s)
        radius = np.tile([0.0035, 0.0025], (len(t), 1))
        pulses = 1.0 + 0.15 * np.sin(2 * np.pi * 25.0 * t)  # short local pressure pulses
        force = 0.35 * np.minimum(t / 0.02, 1.0) * pulses
        return PatchTrack(t, centre, radius, force, ContactState.SLIP, t[-1])
    raise KeyError(f"unknown worked example {name!r}; expected one of {WORKED_EXAMPLES}")


def labelled_sequence(label: ContactState, rng: np.random.Generator, *, duration_s: float = 0.6) -> PatchTrack:
    """One randomised synthetic action labelled by what generated it.

    concentrated: fingertip press near R1 (area 0.2–0.65 cm², 0.3–1.0 N), slow drift ≤ 3 cm/s, force
    wobble ±15 %; one in three is a firm tapping press (3–6 Hz, peaks to 1.6–2.2 N, so the patch briefly
    exceeds the broad-area threshold without ever being stable) and one in six a firm steady press
    (1.8–2.5 N, Hertz patch ≥ 1 cm², 15–25 kPa). distributed: pad stroke near R2
    (area 1.4–2.2 cm², mean pressure 2.8–4.5 kPa) stroking back and forth at 1–3 Hz with peak speed up
    to 14 cm/s and ±4 % force wobble. slip: edge sweep from R3 towards R1 at 18–35 cm/s, oblique, with
    ±20 % pressure pulses.
    """
    if label == ContactState.SLIP:
        speed = rng.uniform(0.18, 0.35)
        x0 = rng.uniform(0.062, 0.072)
        dist = rng.uniform(0.022, 0.032)
        tsweep = dist / speed
        t0 = rng.uniform(0.02, 0.05)
        t = np.arange(0.0, t0 + tsweep + 0.01, DT)
        s = np.clip((t - t0) / tsweep, 0.0, 1.0)
        y0, y1 = rng.uniform(-0.004, 0.004, 2)
        centre = _lerp([x0, y0], [x0 - dist, y1], s)
        r = rng.uniform(0.0025, 0.004)
        radius = np.tile([r * rng.uniform(1.0, 1.4), r], (len(t), 1))
        f = rng.uniform(0.2, 0.6)
        fp = rng.uniform(15.0, 40.0)
        force = f * np.minimum(t / 0.015, 1.0) * (1 + 0.2 * np.sin(2 * np.pi * fp * t + rng.uniform(0, 6.3)))
        return PatchTrack(t, centre, radius, force, label, t0 + SETTLE_S[label])

    t = np.arange(0.0, duration_s, DT)
    ramp = _smooth(t / 0.04)
    heading = rng.uniform(0, 2 * np.pi)
    tapping = False
    freq = 1.0
    if label == ContactState.CONCENTRATED:
        c0 = np.array([rng.uniform(0.030, 0.045), rng.uniform(-0.002, 0.002)])
        drift = rng.uniform(0.0, 0.03)
        area = rng.uniform(0.2e-4, 0.65e-4)
        aspect = rng.uniform(1.0, 1.3)
        f = rng.uniform(0.3, 1.0)
        wob = 0.15
        kind = rng.uniform()
        tapping = kind < 1 / 3
        if kind > 5 / 6:  # firm steady press: the Hertz patch grows past the broad-area threshold
            f = rng.uniform(1.8, 2.5)
            area = 0.5e-4 * (f / 0.65) ** (2 / 3)
            wob = 0.04
    elif label == ContactState.DISTRIBUTED:
        c0 = np.array([rng.uniform(0.045, 0.055), rng.uniform(-0.001, 0.001)])
        drift = rng.uniform(0.0, 0.14)
        freq = rng.uniform(1.0, 3.0)
        area = rng.uniform(1.4e-4, 2.2e-4)
        aspect = rng.uniform(1.6, 2.4)
        f = area * rng.uniform(2800.0, 4500.0)  # mean pressure 2.8–4.5 kPa (paper: 0.48 N / 1.6 cm² = 3 kPa)
        wob = 0.04
    else:
        raise KeyError(f"no labelled sequence for {label!r}")
    # stroke back and forth along the heading (excursion of at most 1 cm, peak speed = drift)
    amp = min(0.01, drift / (2 * np.pi * freq))
    disp = amp * np.sin(2 * np.pi * freq * t)
    centre = c0 + np.outer(disp, [np.cos(heading), 0.3 * np.sin(heading)])
    if tapping:  # firm taps: force 0.2…1 × F_peak at 3–6 Hz, the Hertz patch breathing with it
        f_peak = rng.uniform(1.6, 2.2)
        tap = 0.5 - 0.5 * np.cos(2 * np.pi * rng.uniform(3.0, 6.0) * t)
        force = ramp * f_peak * (0.2 + 0.8 * tap)
        scale = np.maximum(force / f_peak, 0.05) ** (1 / 3) * np.sqrt(1.3e-4 / area)
        radius = np.outer(scale, _radius_for_area(area, aspect))
    else:
        radius = np.outer(np.maximum(ramp, 0.05) ** (1 / 3), _radius_for_area(area, aspect))
        force = f * ramp * (1 + wob * np.sin(2 * np.pi * rng.uniform(1.0, 4.0) * t + rng.uniform(0, 6.3)))
    return PatchTrack(t, centre, radius, force, label, SETTLE_S[label] + 0.04)


def frames(track: PatchTrack, array: SensorArray, *, rng: np.random.Generator | None = None,
           noise_pa: float | None = None) -> list[SensorFrame]:
    """Sensor readings for every sample of ``track`` (noise only when ``rng`` is given)."""
    return [
        array.frame(t, c, r, f, rng=rng, noise_pa=noise_pa)
        for t, c, r, f in zip(track.t, track.centre_m, track.radius_m, track.force_n)
    ]
