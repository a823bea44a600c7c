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
    """Linear per-sample ramps: ``prev`` (C,) then ``tracks`` (T, C) → (C, T·n) (float32 stays float32)."""
    tracks = np.asarray(tracks)
    dtype = np.float32 if tracks.dtype == np.float32 else np.float64
    tracks = tracks.astype(dtype, copy=False)
    start = np.vstack([np.asarray(prev, dtype=dtype)[None, :], tracks[:-1]])  # (T, C)
    r = (np.arange(1, n + 1, dtype=dtype) / dtype(n))[None, None, :]
    s0 = np.ascontiguousarray(start.T)[:, :, None]
    d = np.ascontiguousarray((tracks - start).T)[:, :, None]
    out = np.multiply(d, r)  # (C, T, n), contiguous
    out += s0
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


def resynthesize(tracks: dict[str, np.ndarray], fs: float, carrier_hz=(40.0, 320.0), *,
                 chunk_ticks: int = 512) -> dict[str, np.ndarray]:
    """Render control tracks (:func:`trace_arrays`) vectorised, in cache-sized chunks of ticks.

    Gives the same glove (N,), regions (3, N) and pins (24, N) signals as the tick-by-tick
    renderer (the same 6-oscillator bank: R1–R3, the 40/320 Hz carriers, the glove oscillation),
    from the per-tick amplitudes, frequencies and phases; the pins come back as float32 (within
    1e-6 of the tick path). Ticks must have equal length.
    """
    ns = np.unique(tracks["n"])
    if len(ns) != 1:
        raise ValueError(f"resynthesize needs equal tick lengths, got {ns.tolist()}")
    n = int(ns[0])
    T = len(tracks["n"])
    freq = np.empty((T, 6))
    freq[:, :3], freq[:, 3:5], freq[:, 5] = tracks["beta"], carrier_hz, tracks["glove_hz"]
    amp = np.ones((T, 6))
    amp[:, :3], amp[:, 5] = tracks["region_amp"], tracks["glove_osc"]
    phi = np.zeros((T, 6))
    phi[:, :3] = tracks["phi"]
    # the 24 pins dominate the work: their amplitude ramps and carrier products run in float32
    pin_amp = tracks["pin_amp"].reshape(T, -1).astype(np.float32)  # (T, 2P)
    P = pin_amp.shape[1] // 2
    g_sup = tracks["glove_support"][:, None]
    out_g = np.empty(T * n)
    out_r = np.empty((3, T * n))
    out_p = np.empty((P, T * n), dtype=np.float32)
    r32 = (np.arange(1, n + 1, dtype=np.float32) / np.float32(n))[None, :]
    phase = np.zeros(6)
    prev_a = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
    prev_phi, prev_p, prev_gs = np.zeros(6), np.zeros(2 * P, dtype=np.float32), np.zeros(1)
    for a in range(0, T, chunk_ticks):
        b = min(a + chunk_ticks, T)
        sl = slice(a * n, b * n)
        y, phase = synthesize(fs, n, phase, freq[a:b], prev_a, amp[a:b], prev_phi, phi[a:b])
        out_r[:, sl] = y[:3]
        # per tick: pins (P, n) = [a40_prev, Δa40, a320_prev, Δa320] (P, 4) @ [c40, r·c40, c320, r·c320] (4, n)
        m = b - a
        cur = pin_amp[a:b]
        prv = np.vstack([prev_p[None, :], cur[:-1]])
        d = cur - prv
        A = np.stack([prv[:, :P], d[:, :P], prv[:, P:], d[:, P:]], axis=2)  # (m, P, 4)
        c40 = y[3].astype(np.float32).reshape(m, n)
        c320 = y[4].astype(np.float32).reshape(m, n)
        B = np.stack([c40, c40 * r32, c320, c320 * r32], axis=1)  # (m, 4, n)
        out_p[:, sl] = np.matmul(A, B).transpose(1, 0, 2).reshape(P, -1)
        out_g[sl] = ramp(prev_gs, g_sup[a:b], n)[0] + y[5]
        prev_a, prev_phi, prev_p, prev_gs = amp[b - 1], phi[b - 1], pin_amp[b - 1], g_sup[b - 1]
    for x in (out_g, out_r, out_p):
        np.clip(x, -1.0, 1.0, out=x)
    return {"glove": out_g, "regions": out_r, "pins": out_p}
