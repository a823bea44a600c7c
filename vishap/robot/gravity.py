"""Gravity compensation of the PHANToM (VisHap §2.3 "Gravity Compensation", Eq. 6–7).

Eq. 7 gives the motor torques that hold the arm against gravity::

    τ_g = [0,  g·(m_a·l1 + 0.5·l1·m_c + m_be·l5)·cos θ2,  g·(0.5·m_a·l2 + m_c·l3 − m_df·l6)·sin θ3]

VisHap adjusts ``m_a`` for an attached object (:meth:`PhantomParams.with_adjusted_m_a`); a point
mass ``m_tip`` at the tip adds ``g·m_tip·l1`` and ``g·m_tip·l2`` to the two coefficients exactly
(:attr:`PhantomParams.gravity_coefficients`). Eq. 6 turns τ_g into the compensating tip force
``F_GC = J⁻ᵀ τ_g``.
"""
from __future__ import annotations

import math

import numpy as np

from vishap._core.errors import ShapeError
from vishap.robot.kinematics import torque_to_force
from vishap.robot.params import DEFAULT, PhantomParams

__all__ = ["coefficients", "gravity_torque", "gravity_force", "GravityModel"]


def coefficients(params: PhantomParams = DEFAULT) -> tuple[float, float]:
    """(c2, c3) in N·m: τ_g = (0, c2·cos θ2, c3·sin θ3)."""
    return params.gravity_coefficients


def gravity_torque(q, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Eq. 7: motor torques (N·m) that hold the arm still at ``q`` (rad); (3,) or (N, 3)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (3,):
        raise ShapeError(f"q: expected shape (3,) or (N, 3), got {q.shape}")
    c2, c3 = params.gravity_coefficients
    out = np.zeros_like(q)
    out[..., 1] = c2 * np.cos(q[..., 1])
    out[..., 2] = c3 * np.sin(q[..., 2])
    return out


def gravity_force(q, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Eq. 6 applied to Eq. 7: the tip force ``F_GC`` (N, robot frame) that compensates gravity."""
    return torque_to_force(q, gravity_torque(q, params), params)


class GravityModel:
    """Eq. 7 with its coefficients cached, for the servo loop.

    ``m_a`` may be changed while running (VisHap adjusts it when an object is attached);
    :meth:`set_tip_mass` models the object as a point mass at the tip instead.
    """

    def __init__(self, params: PhantomParams = DEFAULT):
        self.params = params
        self.c2, self.c3 = params.gravity_coefficients

    @property
    def m_a(self) -> float:
        return self.params.m_a

    def set_m_a(self, m_a: float) -> None:
        """Use ``m_a`` (kg) for link a (forearm plus whatever VisHap folds into it)."""
        if not (math.isfinite(m_a) and m_a >= 0.0):
            raise ValueError(f"m_a: expected a finite mass ≥ 0 kg, got {m_a!r}")
        from dataclasses import replace

        self.params = replace(self.params, m_a=float(m_a))
        self.c2, self.c3 = self.params.gravity_coefficients

    def set_tip_mass(self, m_tip: float) -> None:
        """Model an attached object of ``m_tip`` kg as a point mass at the tip."""
        if not (math.isfinite(m_tip) and m_tip >= 0.0):
            raise ValueError(f"m_tip: expected a finite mass ≥ 0 kg, got {m_tip!r}")
        self.params = self.params.with_tip_mass(m_tip)
        self.c2, self.c3 = self.params.gravity_coefficients

    def torque(self, q) -> np.ndarray:
        return gravity_torque(q, self.params)

    def torque_scalar(self, t2: float, t3: float) -> tuple[float, float]:
        """(τ2, τ3) on floats; τ1 is always 0."""
        return self.c2 * math.cos(t2), self.c3 * math.sin(t3)
