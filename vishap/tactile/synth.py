"""Phase-continuous synthesis of the drive signals (default 10 kHz per channel; PHSM §2.5).

Control runs per tick (1 ms); signals are sampled ``n`` times per tick. Within tick k each channel's
amplitude (and phase offset) ramps linearly from its value at the end of tick k−1 to its value at
tick k, and the oscillator phase accumulates 2π·f_k/fs per sample, so neither amplitude, phase nor
frequency changes ever produce a step in the waveform. The same function renders one tick (the
1 kHz ``TactileRenderer.step``) or a whole sequence of ticks at once (vectorised; used by
``render`` and the real-time benchmark) with identical results.
"""
from __future__ import annotations

import numpy as np

__all__ = ["synthesize", "ramp", "Oscillators", "trace_arrays", "resynthesize"]


def ramp(prev: np.ndarray, tracks: np.ndarray, n: int) -> np.ndarray:
    """Linear per-sample ramps: ``prev`` (C,) then ``tracks`` (T, C) → (C, T·n)."""
    tracks = np.asarray(tracks, dtype=np.float64)
    start = np.vstack([np.asarray(prev, dtype=np.float64)[None, :], tracks[:-1]])  # (T, C)
    r = (np.arange(1, n + 1) / n)[None, None, :]
    s0 = np.ascontiguousarray(start.T)[:, :, None]
    d = np.ascontiguousarray((tracks - start).T)[:, :, None]
    out = s0 + d * r  # (C, T, n), contiguous
    return out.reshape(tracks.shape[1], -1)


def synthesize(fs: float, n: int, phase0: np.ndarray, freq_hz: np.ndarray, amp_prev: np.ndarray, amp: np.ndarray,
               phi_prev: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sum-free oscillator bank: channel c, tick k, sample j of ``n``:

        y = A_ckj · cos(θ_c(k, j) + φ_ckj),   θ advances by 2π f_ck / fs per sample.

    ``freq_hz``, ``amp``, ``phi``: (T, C); ``phase0``, ``amp_prev``, ``phi_prev``: (C,).
    Returns the signals (C, T·n) and the carrier phases after the last sample (C,).
    """
    freq_hz = np.asarray(freq_hz, dtype=np.float64)
    T, C = freq_hz.shape
    w = 2.0 * np.pi * freq_hz / fs  # (T, C) rad/sample
    start = np.asarray(phase0, dtype=np.float64)[None, :] + np.vstack([np.zeros((1, C)), np.cumsum(w * n, axis=0)[:-1]])
    j = np.arange(n)[None, None, :]
    theta = (np.ascontiguousarray(start.T)[:, :, None] + np.ascontiguousarray(w.T)[:, :, None] * j).reshape(C, -1)
    end = np.mod(start[-1] + w[-1] * n, 2.0 * np.pi)
    theta += ramp(phi_prev, phi, n)
    np.cos(theta, out=theta)
    theta *= ramp(amp_prev, amp, n)
    y = theta
    return y, end


class Oscillators:
    """A bank of C phase-continuous oscillators with remembered amplitude/phase offsets."""

    def __init__(self, n_channels: int, fs: float):
        self.fs = fs
        self.phase = np.zeros(n_channels)
        self.amp = np.zeros(n_channels)
        self.phi = np.zeros(n_channels)

    def reset(self) -> None:
        self.phase[:] = 0.0
        self.amp[:] = 0.0
        self.phi[:] = 0.0

    def run(self, n: int, freq_hz, amp, phi) -> np.ndarray:
        """Render one tick of ``n`` samples; returns (C, n). Same result as :func:`synthesize` with T = 1."""
        freq_hz = np.asarray(freq_hz, dtype=np.float64)
        amp = np.asarray(amp, dtype=np.float64)
        phi = np.asarray(phi, dtype=np.float64)
        if n != getattr(self, "_n", None):
            self._n = n
            self._j = np.arange(n, dtype=np.float64)
            self._r = np.arange(1, n + 1, dtype=np.float64) / max(n, 1)
        w = (2.0 * np.pi / self.fs) * freq_hz
        theta = self.phase[:, None] + w[:, None] * self._j
        a = self.amp[:, None] + (amp - self.amp)[:, None] * self._r
        ph = self.phi[:, None] + (phi - self.phi)[:, None] * self._r
        y = a * np.cos(theta + ph)
        self.phase = np.mod(self.phase + w * n, 2.0 * np.pi)
        self.amp, self.phi = amp.copy(), phi.copy()
        return y


def trace_arrays(trace: list[dict]) -> dict[str, np.ndarray]:
    """Stack a recorded per-tick control trace (``TactileRenderer.record``) into arrays (leading axis T)."""
    if not trace:
        raise ValueError("empty trace")
    return {k: np.array([d[k] for d in trace]) for k in trace[0]}


def resynthesize(tracks: dict[str, np.ndarray], fs: float, carrier_hz=(40.0, 320.0)) -> dict[str, np.ndarray]:
    """Render control tracks (:func:`trace_arrays`) in one vectorised pass.

    Gives the same glove (N,), regions (3, N) and pins (24, N) signals as the tick-by-tick
    renderer, from the per-tick amplitudes, frequencies and phases. Ticks must have equal length.
    """
    ns = np.unique(tracks["n"])
    if len(ns) != 1:
        raise ValueError(f"resynthesize needs equal tick lengths, got {ns.tolist()}")
    n = int(ns[0])
    T = len(tracks["n"])
    regions, _ = synthesize(fs, n, np.zeros(3), tracks["beta"], np.zeros(3), tracks["region_amp"], np.zeros(3),
                            tracks["phi"])
    car_f = np.broadcast_to(np.asarray(carrier_hz, dtype=np.float64), (T, 2))
    car, _ = synthesize(fs, n, np.zeros(2), car_f, np.ones(2), np.ones((T, 2)), np.zeros(2), np.zeros((T, 2)))
    pin_amp = tracks["pin_amp"]  # (T, 2, P)
    P = pin_amp.shape[2]
    a = ramp(np.zeros(2 * P), pin_amp.reshape(T, 2 * P), n).reshape(2, P, -1)
    a[0] *= car[0]
    a[1] *= car[1]
    pins = np.add(a[0], a[1], out=a[0])
    support = ramp(np.zeros(1), tracks["glove_support"][:, None], n)[0]
    osc, _ = synthesize(fs, n, np.zeros(1), tracks["glove_hz"][:, None], np.zeros(1), tracks["glove_osc"][:, None],
                        np.zeros(1), np.zeros((T, 1)))
    glove = support + osc[0]
    return {"glove": np.clip(glove, -1, 1), "regions": np.clip(regions, -1, 1), "pins": np.clip(pins, -1, 1, out=pins)}
