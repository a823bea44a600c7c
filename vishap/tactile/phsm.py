"""Perceptual Haptic Spectrum Model: surface attributes → multi-band targets (PHSM §2.1, §2.2).

Each contact event becomes one target per perceptual band — 0–20 Hz force cues, 20–200 Hz texture
microvibration and friction, 200–400 Hz fine microtexture and sliding tremor — described by
amplitude (0–1), dominant frequency, bandwidth and a temporal envelope (attack/release).

The mapping, "reverse-encoded" from what should be felt (§2.1):

* force band: amplitude from the normal force and hardness (pressing resistance); dominant
  frequency from hardness and damping (stiff, elastic surfaces rebound faster); bandwidth and the
  envelope from viscoelasticity (slow, smeared deformation);
* texture lines: a microtexture of period p stroked at speed v vibrates at k·v/p (k = 1…K) with
  amplitudes roughness/k^(1+hardness) (softer weaves have richer harmonics); each line is assigned
  to the band it falls in; the band amplitude is their root-sum-square, the dominant frequency the
  strongest line, the bandwidth their energy-weighted spread;
* friction modulation adds broadband energy to the texture band (stick–slip), growing with μ and
  speed. Texture bands are silent when the finger does not slide.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap.tactile.config import BandConfig, SurfaceAttributes

__all__ = ["BandTarget", "phsm_targets", "band_index"]


@dataclass(frozen=True)
class BandTarget:
    """Perceptual target for one band."""

    band: str
    amplitude: float
    frequency_hz: float
    bandwidth_hz: float
    attack_s: float
    release_s: float


def band_index(freq_hz: float, bands: list[BandConfig]) -> int:
    """Index of the band containing ``freq_hz`` (upper edges belong to the lower band)."""
    for i, b in enumerate(bands):
        if freq_hz <= b.high_hz:
            return i
    return len(bands) - 1


def phsm_targets(attrs: SurfaceAttributes, speed_m_s: float, force_n: float, bands: list[BandConfig], *,
                 force_full_n: float = 1.5, n_harmonics: int = 6, speed_ref_m_s: float = 0.05) -> list[BandTarget]:
    """Multi-band targets for a contact at tangential ``speed_m_s`` with normal ``force_n``."""
    speed = max(float(speed_m_s), 0.0)
    load = min(max(force_n / force_full_n, 0.0), 1.0)
    h, e, r, mu, ve = attrs.hardness, attrs.elasticity, attrs.roughness, attrs.friction, attrs.viscoelasticity
    attack = 0.005 + 0.045 * ve
    release = attack * (1.0 + e)

    out: list[BandTarget] = []
    # force band (0–20 Hz)
    b0 = bands[0]
    f0 = b0.low_hz + (b0.high_hz - b0.low_hz) * (0.1 + 0.8 * h * (1.0 - 0.5 * ve))
    out.append(BandTarget(b0.name, load * (0.4 + 0.6 * h), float(f0), float((b0.high_hz - b0.low_hz) * (0.1 + 0.4 * ve)),
                          attack, release))

    # texture lines k·v/p
    motion = speed / (speed + speed_ref_m_s)  # 0 at rest, → 1 when sliding
    k = np.arange(1, n_harmonics + 1)
    f_lines = k * speed / attrs.texture_period_m
    a_lines = r / k ** (1.0 + h)
    highs = np.array([b.high_hz for b in bands])
    idx = np.minimum(np.searchsorted(highs, f_lines, side="left"), len(bands) - 1)
    friction_amp = min(1.0, mu) * 0.5 * motion * (0.3 + 0.7 * load)
    for i, b in enumerate(bands[1:], start=1):
        sel = (idx == i) & (f_lines >= b.low_hz) & (f_lines > 0)
        a = a_lines[sel] * motion
        fl = f_lines[sel]
        extra = friction_amp if i == 1 else 0.0
        amp = float(np.sqrt(np.sum(a**2) + extra**2))
        if a.size:
            dom = float(fl[np.argmax(a)])
            w = a**2 / np.sum(a**2)
            spread = float(np.sqrt(np.sum(w * (fl - np.sum(w * fl)) ** 2)))
        else:
            dom = float(np.sqrt(max(b.low_hz, 1.0) * b.high_hz))
            spread = 0.0
        bw = spread + (0.25 * (b.high_hz - b.low_hz) * min(1.0, mu) if extra > 0 else 0.0)
        out.append(BandTarget(b.name, min(amp, 1.0), dom, float(bw), attack, release))
    return out
