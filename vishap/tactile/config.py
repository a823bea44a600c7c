"""Validated configuration of the tactile sleeve (PHSM §2.1–2.5, §3.1; HAPTEX §II-C, §III-B).

Every number the tactile layer uses lives in ``tactile.yaml`` beside this module and is checked on
load by the pydantic schemas below. The regional parameters keep the paper's units and ranges
(§3.1): α ∈ [0.2, 1], β ∈ [20, 400] Hz, λ ∈ [1, 10] per cm, φ ∈ [0, π], γ ∈ [0, 2], with the
region centres μ in cm along the finger sleeve — hence the ``_cm`` / ``_per_cm`` names. Everything
else is SI. A bad value raises :class:`~vishap._core.errors.ConfigError` naming the field.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator

from vishap._core.config import Schema, load_config, validate

__all__ = [
    "BandConfig",
    "RegionParams",
    "SensorConfig",
    "ClassifierConfig",
    "ControlRules",
    "PinConfig",
    "FeedForwardConfig",
    "AllocationConfig",
    "SurfaceAttributes",
    "TactileConfig",
    "DEFAULT_CONFIG_PATH",
    "load_tactile_config",
    "tactile_config_from_dict",
]

DEFAULT_CONFIG_PATH = Path(__file__).with_name("tactile.yaml")

#: The full rendering band of the sleeve (PHSM §2.1): 0–400 Hz.
BAND_MAX_HZ = 400.0


class BandConfig(Schema):
    """One PHSM perceptual band with its JND (Weber-fraction) interval (§2.1, §2.2)."""

    name: str
    low_hz: float = Field(ge=0.0, le=BAND_MAX_HZ)
    high_hz: float = Field(gt=0.0, le=BAND_MAX_HZ)
    weber_amplitude: float = Field(gt=0.0, lt=1.0, description="relative amplitude JND")
    weber_frequency: float = Field(gt=0.0, lt=1.0, description="relative frequency JND")
    detection_threshold: float = Field(ge=0.0, lt=1.0, description="amplitude below which the band is off")

    @model_validator(mode="after")
    def _ordered(self):
        if self.high_hz <= self.low_hz:
            raise ValueError(f"high_hz ({self.high_hz}) must exceed low_hz ({self.low_hz})")
        return self


class RegionParams(Schema):
    """Parameters of one sub-perceptual region Rᵢ in Ψ(x, t) (§2.3, ranges of §3.1)."""

    alpha: float = Field(ge=0.2, le=1.0, description="static intensity factor αᵢ")
    lambda_per_cm: float = Field(ge=1.0, le=10.0, description="spatial attenuation λᵢ, 1/cm")
    mu_cm: float = Field(ge=0.0, le=12.0, description="region centre μᵢ along the sleeve, cm")
    beta_hz: float = Field(ge=20.0, le=BAND_MAX_HZ, description="feedback frequency βᵢ, Hz")
    phi_rad: float = Field(ge=0.0, le=math.pi + 1e-9, description="initial phase φᵢ, rad")
    gamma: float = Field(ge=0.0, le=2.0, description="dynamic gain γᵢ(t)")


class SensorConfig(Schema):
    """The flexible strain-sensor array on the index-finger sleeve (§2.3, §3.1)."""

    rows: int = Field(ge=1, le=64, description="elements across the finger")
    cols: int = Field(ge=2, le=128, description="elements along the finger")
    pitch_m: float = Field(gt=0.0, le=0.01, description="element pitch (square elements)")
    x0_m: float = Field(ge=0.0, description="sleeve coordinate of the first column centre")
    engage_pressure_pa: float = Field(gt=0.0, description="element pressure counted as engaged")
    noise_pa: float = Field(ge=0.0, description="default sensor noise (std) for synthetic data")
    contact_radius_ref_m: float = Field(gt=0.0, description="Hertz patch radius at force_ref_n")
    force_ref_n: float = Field(gt=0.0)
    default_pad_x_m: float = Field(ge=0.0, description="pad contact centre when a sample gives none")
    flat_pad_x_m: float = Field(ge=0.0, description="contact centre of a finger lying flat (finger pad, R2)")
    pitch_flat_rad: float = Field(ge=0.0, le=1.5708, description="finger pitch at or below which the pad lies flat")
    pitch_tip_rad: float = Field(ge=0.0, le=1.5708, description="finger pitch from which only the tip touches")
    flat_elongation: float = Field(ge=0.0, description="extra patch length along the finger when flat (× radius)")
    flat_widening: float = Field(ge=0.0, description="extra patch width across the finger when flat (× radius)")
    subsamples: int = Field(ge=1, le=7, description="integration points per element side")


class ClassifierConfig(Schema):
    """Contact-state rules of §2.4 / §3.1 (slip: >15 cm/s and pulses <100 ms; distributed: broad,
    stable >250 ms; concentrated: small area, high peak)."""

    slip_speed_m_s: float = Field(gt=0.0)
    slip_pulse_max_s: float = Field(gt=0.0)
    distributed_area_m2: float = Field(gt=0.0, description="area from which a contact is broad")
    stable_time_s: float = Field(gt=0.0)
    stable_force_cv: float = Field(gt=0.0, lt=1.0, description="max coefficient of variation of force")
    concentrated_pressure_pa: float = Field(gt=0.0, description="mean contact pressure from which even a broad, "
                                            "stable contact counts as concentrated (high local pressure)")
    min_force_n: float = Field(gt=0.0, description="total force below which there is no contact")
    velocity_window_s: float = Field(gt=0.0, description="centroid-velocity regression window")
    hold_s: float = Field(ge=0.0, description="a new state must persist this long before switching")


class ControlRules(Schema):
    """Regional control rules of §3.2–3.4 and the continuity limits of §2.4."""

    distributed_gamma2: float = Field(ge=0.0, le=2.0)
    distributed_beta2_hz: float = Field(ge=20.0, le=BAND_MAX_HZ)
    distributed_alpha2: float = Field(ge=0.2, le=1.0)
    slip_gamma3: float = Field(ge=0.0, le=2.0)
    slip_beta3_hz: float = Field(ge=20.0, le=BAND_MAX_HZ)
    slip_phase_delay_rad: float = Field(ge=0.0, le=math.pi)
    gamma_slew_per_s: float = Field(gt=0.0, description="max |dγ/dt|")
    alpha_slew_per_s: float = Field(gt=0.0, description="max |dα/dt|")
    beta_slew_hz_per_s: float = Field(gt=0.0, description="max |dβ/dt|")
    amplitude_slew_per_s: float = Field(gt=0.0, description="max |dA/dt| of any channel amplitude")
    phase_slew_rad_per_s: float = Field(gt=0.0, description="max |dφ/dt|")
    spatial_kernel: Literal["decay", "paper"] = "decay"


class PinConfig(Schema):
    """HAPTEX tactile renderer (§II-C, §III-B)."""

    rows: int = Field(ge=1, le=16)
    cols: int = Field(ge=1, le=16)
    pitch_m: float = Field(gt=0.0)
    centre_pad_x_m: float = Field(ge=0.0, description="sleeve coordinate of the array centre")
    update_hz: float = Field(gt=0.0, le=1000.0)
    contact_rate_hz: float = Field(gt=0.0)
    antialias_hz: float = Field(gt=0.0)
    f_low_hz: float = Field(gt=0.0, le=BAND_MAX_HZ)
    f_high_hz: float = Field(gt=0.0, le=BAND_MAX_HZ)
    filter_octaves: float = Field(gt=0.0, description="band-pass half-width (Gaussian σ), octaves")
    tile_grid_m: float = Field(gt=0.0, description="pseudo-topology resolution")
    map_grid_m: float = Field(gt=0.0, description="non-uniformity map resolution")
    map_size_m: float = Field(gt=0.0)
    k_force_per_n: float = Field(gt=0.0, description="k_F: intensity per newton")
    amplitude_ref_m: float = Field(gt=0.0, description="spectral amplitude giving unit drive")

    @model_validator(mode="after")
    def _order(self):
        if self.f_high_hz <= self.f_low_hz:
            raise ValueError("f_high_hz must exceed f_low_hz")
        if self.antialias_hz >= self.contact_rate_hz / 2:
            raise ValueError("antialias_hz must be below the Nyquist rate of contact_rate_hz")
        return self


class FeedForwardConfig(Schema):
    """Short-horizon kinematic prediction (§2.4): pre-arm channels 5–10 ms ahead."""

    horizon_s: float = Field(ge=0.005, le=0.010)
    min_approach_speed_m_s: float = Field(ge=0.0)
    accel_filter_s: float = Field(gt=0.0, description="time constant of the acceleration estimate")
    prearm_timeout_s: float = Field(gt=0.0, description="pre-arm without contact after this is dropped")
    prearm_level: float = Field(gt=0.0, le=1.0, description="envelope the pre-arm ramp may reach before contact")
    enabled: bool = True


class AllocationConfig(Schema):
    """Dual actuation (§2.5, Table 1): glove 0–20 Hz, sleeve 20–400 Hz, weights per state."""

    glove_band_hz: tuple[float, float]
    sleeve_band_hz: tuple[float, float]
    sample_rate_hz: float = Field(ge=1000.0, le=96000.0)
    glove_weight: dict[str, float]
    sleeve_weight: dict[str, float]
    texture_delay_s: dict[str, float]
    glove_force_full_n: float = Field(gt=0.0, description="force mapped to unit glove support")
    static_texture_gain: float = Field(ge=0.0, le=1.0, description="texture level of a still press per unit roughness")
    glove_oscillation_gain: float = Field(ge=0.0, le=1.0, description="share of the force band's oscillation on the glove")

    @field_validator("glove_weight", "sleeve_weight", "texture_delay_s")
    @classmethod
    def _states(cls, v: dict[str, float]):
        need = {"none", "concentrated", "distributed", "slip"}
        if set(v) != need:
            raise ValueError(f"keys must be exactly {sorted(need)}, got {sorted(v)}")
        if any(not (0.0 <= w <= 2.0) for w in v.values()):
            raise ValueError("values must lie in [0, 2]")
        return v

    @model_validator(mode="after")
    def _bands(self):
        g0, g1 = self.glove_band_hz
        s0, s1 = self.sleeve_band_hz
        if not (0.0 <= g0 < g1 <= 20.0):
            raise ValueError(f"glove_band_hz must lie within [0, 20] Hz, got {self.glove_band_hz}")
        if not (20.0 <= s0 < s1 <= BAND_MAX_HZ):
            raise ValueError(f"sleeve_band_hz must lie within [20, 400] Hz, got {self.sleeve_band_hz}")
        if self.sample_rate_hz < 2.5 * s1:
            raise ValueError("sample_rate_hz must be at least 2.5× the sleeve band's top")
        return self


class SurfaceAttributes(Schema):
    """Virtual surface attributes, the PHSM input space (§2.1). Dimensionless ones are in [0, 1]."""

    hardness: float = Field(ge=0.0, le=1.0)
    elasticity: float = Field(ge=0.0, le=1.0)
    roughness: float = Field(ge=0.0, le=1.0)
    friction: float = Field(ge=0.0, le=2.0, description="kinetic friction coefficient")
    viscoelasticity: float = Field(ge=0.0, le=1.0)
    texture_period_m: float = Field(gt=0.0, le=0.02, description="microtexture period")


class TactileConfig(Schema):
    """Top level of ``tactile.yaml``."""

    bands: list[BandConfig]
    regions: list[RegionParams]
    presets: dict[str, list[RegionParams]]
    sensor: SensorConfig
    classifier: ClassifierConfig
    control: ControlRules
    pins: PinConfig
    feedforward: FeedForwardConfig
    allocation: AllocationConfig
    surfaces: dict[str, SurfaceAttributes]

    @field_validator("bands")
    @classmethod
    def _three_bands(cls, v: list[BandConfig]):
        if len(v) != 3:
            raise ValueError(f"expected the 3 PHSM bands, got {len(v)}")
        for a, b in zip(v, v[1:]):
            if abs(a.high_hz - b.low_hz) > 1e-9:
                raise ValueError(f"bands must be contiguous: {a.name} ends at {a.high_hz}, {b.name} starts at {b.low_hz}")
        return v

    @field_validator("regions")
    @classmethod
    def _three_regions(cls, v: list[RegionParams]):
        if len(v) != 3:
            raise ValueError(f"expected regions R1–R3, got {len(v)}")
        return v

    @field_validator("presets")
    @classmethod
    def _preset_regions(cls, v: dict[str, list[RegionParams]]):
        for name, regs in v.items():
            if len(regs) != 3:
                raise ValueError(f"preset {name!r}: expected 3 regions, got {len(regs)}")
        return v


def load_tactile_config(path: str | os.PathLike | None = None) -> TactileConfig:
    """Load and validate a tactile configuration (default: ``tactile.yaml`` beside this module)."""
    return load_config(DEFAULT_CONFIG_PATH if path is None else path, TactileConfig)


def tactile_config_from_dict(data: dict, *, file: str | None = None) -> TactileConfig:
    """Validate an in-memory mapping (e.g. an edited copy of the defaults)."""
    return validate(TactileConfig, data, file=file)
