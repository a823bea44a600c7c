"""Region-specific response Ψ(x, t) over R1–R3 and the contact-state control rules (PHSM §2.3, §3.2–3.4).

    Ψ(x, t) = Σᵢ αᵢ · (1 − e^(−λᵢ|x − μᵢ|)) · cos(2π βᵢ t + φᵢ) · γᵢ(t)

with x and μᵢ in cm along the sleeve and λᵢ in 1/cm (the paper's units). ``kernel="paper"``
evaluates this literally. Taken literally the spatial factor is *zero* at a region's own centre,
which contradicts the paper's own §3.2 example (pressing at x = μ₁ "places primary emphasis on R1"
and drives the fingertip actuator at β₁ = 320 Hz); ``kernel="decay"`` (the default) uses the
attenuation e^(−λᵢ|x − μᵢ|) that §2.3 describes ("spatial attenuation centred on each region"), for
which the §3.2 example does emphasise R1. Both are available and tested.

Control rules (§3.3, §3.4): distributed contact raises γ₂ to 1.5 and lowers α₂ and β₂
(160 → 120 Hz); slip raises γ₃ to 1.7, sets β₃ = 280 Hz and delays R3's phase by 0.3π (normal
support is reduced in the allocation stage). :class:`RegionController` moves the live parameters
towards each state's target under slew limits, so no parameter — and no amplitude — ever jumps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vishap.tactile.classifier import ContactState
from vishap.tactile.config import ControlRules, RegionParams, TactileConfig

__all__ = ["RegionSet", "spatial_weight", "psi", "preset", "target_regions", "RegionController"]


@dataclass
class RegionSet:
    """Parameters of R1–R3 as arrays of shape (3,): α, λ (1/cm), μ (cm), β (Hz), φ (rad), γ."""

    alpha: np.ndarray
    lambda_per_cm: np.ndarray
    mu_cm: np.ndarray
    beta_hz: np.ndarray
    phi_rad: np.ndarray
    gamma: np.ndarray

    @classmethod
    def from_params(cls, params: list[RegionParams]) -> RegionSet:
        def col(name):
            return np.array([getattr(p, name) for p in params], dtype=np.float64)

        return cls(col("alpha"), col("lambda_per_cm"), col("mu_cm"), col("beta_hz"), col("phi_rad"), col("gamma"))

    def copy(self) -> RegionSet:
        return RegionSet(*(np.array(getattr(self, f)) for f in self.fields()))

    @staticmethod
    def fields() -> tuple[str, ...]:
        return ("alpha", "lambda_per_cm", "mu_cm", "beta_hz", "phi_rad", "gamma")

    def as_dict(self) -> list[dict[str, float]]:
        """Per region, the paper's symbols (α, λ, μ, β, φ, γ) in the paper's units."""
        return [
            {
                "region": f"R{i + 1}",
                "alpha": float(self.alpha[i]),
                "lambda_per_cm": float(self.lambda_per_cm[i]),
                "mu_cm": float(self.mu_cm[i]),
                "beta_hz": float(self.beta_hz[i]),
                "phi_rad": float(self.phi_rad[i]),
                "phi_over_pi": float(self.phi_rad[i] / math.pi),
                "gamma": float(self.gamma[i]),
            }
            for i in range(3)
        ]


def spatial_weight(x_cm, rs: RegionSet, kernel: str = "decay") -> np.ndarray:
    """Spatial factor of each region at sleeve position(s) ``x_cm``: shape (3,) or (3, N)."""
    x = np.asarray(x_cm, dtype=np.float64)
    d = np.abs(x[..., None] - rs.mu_cm) if x.ndim else np.abs(x - rs.mu_cm)
    decay = np.exp(-rs.lambda_per_cm * d)
    w = decay if kernel == "decay" else 1.0 - decay
    return w.T if x.ndim else w


def psi(x_cm, t, rs: RegionSet, kernel: str = "paper") -> np.ndarray:
    """Ψ(x, t) of §2.3 for scalar ``x_cm`` and times ``t`` (s); literal formula by default."""
    t = np.asarray(t, dtype=np.float64)
    w = spatial_weight(float(x_cm), rs, kernel)  # (3,)
    osc = np.cos(2 * np.pi * rs.beta_hz[:, None] * t.reshape(1, -1) + rs.phi_rad[:, None])
    out = ((rs.alpha * w * rs.gamma)[:, None] * osc).sum(axis=0)
    return out.reshape(t.shape)


def preset(name: str, cfg: TactileConfig) -> RegionSet:
    """A named parameter set of §3.2–3.4 (``concentrated``, ``distributed``, ``slip``) as written in the config."""
    if name not in cfg.presets:
        from vishap._core.errors import ConfigError

        raise ConfigError(f"unknown preset {name!r}; expected one of {sorted(cfg.presets)}", field="presets")
    return RegionSet.from_params(cfg.presets[name])


def target_regions(state: ContactState, cfg: TactileConfig) -> RegionSet:
    """Regional parameters the controller uses in ``state``: the state's preset with the control
    rules applied on top (rules are the source of truth for the fields they name)."""
    rules: ControlRules = cfg.control
    if state in (ContactState.NONE, ContactState.CONCENTRATED):
        # out of contact the parameters rest at (and are pre-armed to) the fingertip set; the
        # output itself is gated by the channel envelopes, not by γ
        return preset("concentrated", cfg) if "concentrated" in cfg.presets else RegionSet.from_params(cfg.regions)
    rs = preset(state.value, cfg)
    base = preset("concentrated", cfg)
    if state == ContactState.DISTRIBUTED:
        rs.gamma[1] = rules.distributed_gamma2
        rs.beta_hz[1] = rules.distributed_beta2_hz
        rs.alpha[1] = rules.distributed_alpha2
    elif state == ContactState.SLIP:
        rs.gamma[2] = rules.slip_gamma3
        rs.beta_hz[2] = rules.slip_beta3_hz
        rs.phi_rad[2] = min(base.phi_rad[2] + rules.slip_phase_delay_rad, math.pi)
    return rs


def _slew(cur: np.ndarray, target: np.ndarray, step: float) -> np.ndarray:
    return cur + np.minimum(np.maximum(target - cur, -step), step)


class RegionController:
    """Live regional parameters, slewed towards the target of the current contact state."""

    def __init__(self, cfg: TactileConfig):
        self.cfg = cfg
        self._targets = {s: target_regions(s, cfg) for s in ContactState}
        self.params = self._targets[ContactState.NONE].copy()

    def target(self, state: ContactState) -> RegionSet:
        return self._targets[state]

    def reset(self) -> None:
        self.params = self._targets[ContactState.NONE].copy()

    def update(self, state: ContactState, dt: float, *, silent: bool = False) -> RegionSet:
        """Slew towards ``state``'s target; while the output is ``silent`` (envelope ≈ 0) the
        parameters are set at once — this is how a pre-arm readies the channels before contact."""
        r = self.cfg.control
        tgt = self._targets[state]
        if silent:
            self.params = tgt.copy()
            return self.params
        p = self.params
        p.gamma = _slew(p.gamma, tgt.gamma, r.gamma_slew_per_s * dt)
        p.alpha = _slew(p.alpha, tgt.alpha, r.alpha_slew_per_s * dt)
        p.beta_hz = _slew(p.beta_hz, tgt.beta_hz, r.beta_slew_hz_per_s * dt)
        p.phi_rad = _slew(p.phi_rad, tgt.phi_rad, r.phase_slew_rad_per_s * dt)
        p.lambda_per_cm = tgt.lambda_per_cm.copy()
        p.mu_cm = tgt.mu_cm.copy()
        return p
