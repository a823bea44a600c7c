"""Dual-actuation channel allocation (PHSM §2.4, §2.5 and Table 1).

Two layers share the contact: the primary glove channel renders 0–20 Hz force support (gross
pressure, resistance, compliance) and the secondary sleeve channels render 20–400 Hz texture (the
three regional actuators R1–R3 and the 24 HAPTEX pins). Dominance is reassigned per contact state
with the weights in ``allocation`` of the config:

* concentrated — local high-frequency texture at the dominant region, moderate force support;
* distributed — force support first and full, texture lower and delayed (``texture_delay_s``:
  "low-frequency support develops first, followed by lower-amplitude texture modulation", §3.3);
* slip — normal support reduced, phase-modulated local texture emphasised (§3.4).

Regional amplitudes follow Ψ's factors αᵢ·γᵢ·wᵢ(x) scaled by the PHSM level of the band that βᵢ
falls in, and are normalised so that their sum never exceeds 1 (§2.2, normalisation across channels).
x may be the span [x_min, x_max] the contact centroid covered over the last ~150 ms: |x − μᵢ| is then
the distance from μᵢ to that span, so a slip that sweeps from the lateral edge (R3) across the pad
keeps R3 engaged (§3.4 "shifts priority toward R3"), while a still press reduces to the point x.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap.tactile.classifier import ContactState
from vishap.tactile.config import TactileConfig
from vishap.tactile.regions import RegionSet, spatial_weight

__all__ = ["ChannelTargets", "allocate"]


@dataclass(frozen=True)
class ChannelTargets:
    """Per-tick amplitude targets before the continuity limits."""

    glove_support: float          # 0–1, slowly varying force support (glove, < 20 Hz)
    glove_osc_amp: float          # force-band oscillation on the glove
    glove_osc_hz: float           # ≤ 20 Hz
    region_amp: np.ndarray        # (3,)
    sleeve_gain: float            # texture gain of the sleeve (regions and pins) in this state


_HIGHS: dict[int, np.ndarray] = {}


def _band_highs(cfg: TactileConfig) -> np.ndarray:
    key = id(cfg.bands)
    if key not in _HIGHS:
        _HIGHS[key] = np.array([b.high_hz for b in cfg.bands])
    return _HIGHS[key]


def allocate(state: ContactState, force_n: float, band_amp: np.ndarray, band_hz: np.ndarray, regions: RegionSet,
             x_cm: float | tuple[float, float], roughness: float, cfg: TactileConfig, *,
             time_in_state_s: float = np.inf) -> ChannelTargets:
    """Channel targets for one tick (see the module docstring for the rules)."""
    al = cfg.allocation
    key = state.value
    load = min(max(force_n / al.glove_force_full_n, 0.0), 1.0)
    glove_w = al.glove_weight[key]
    g_lo, g_hi = al.glove_band_hz
    osc_hz = min(max(float(band_hz[0]), g_lo), g_hi)
    sleeve = al.sleeve_weight[key] if time_in_state_s >= al.texture_delay_s[key] else 0.0

    if isinstance(x_cm, tuple):  # distance from each μᵢ to the swept span (0 inside it)
        lo, hi = x_cm
        x_eff = np.minimum(np.maximum(regions.mu_cm, lo), hi)
        d = np.abs(x_eff - regions.mu_cm)
        decay = np.exp(-regions.lambda_per_cm * d)
        w = decay if cfg.control.spatial_kernel == "decay" else 1.0 - decay
    else:
        w = spatial_weight(x_cm, regions, cfg.control.spatial_kernel)
    highs = _band_highs(cfg)
    level = np.asarray(band_amp)[np.minimum(np.searchsorted(highs, regions.beta_hz), len(highs) - 1)]
    level = np.minimum(level + al.static_texture_gain * roughness, 1.0)
    amp = regions.alpha * regions.gamma * w * level
    total = amp.sum()
    if total > 1.0:
        amp = amp / total
    return ChannelTargets(
        glove_support=glove_w * load,
        glove_osc_amp=al.glove_oscillation_gain * glove_w * float(band_amp[0]),
        glove_osc_hz=osc_hz,
        region_amp=amp,
        sleeve_gain=sleeve,
    )
