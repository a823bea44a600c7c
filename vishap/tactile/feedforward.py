"""Short-horizon predictive feed-forward (PHSM §2.4).

Rule-based kinematic estimation: from the finger's height above the surface h (object frame, z
along the normal), its normal velocity v and a low-passed acceleration a, the predictor solves
h + v·τ + ½·a·τ² = 0 for the first time-to-contact τ. When τ lies within the horizon (5–10 ms) and
the finger approaches faster than ``min_approach_speed_m_s``, the channels are *pre-armed*: the
renderer sets the parameters for the predicted state (slip if the finger is also moving along the
surface faster than the slip speed, concentrated otherwise) and starts the continuity-limited
amplitude ramp, so texture reaches the skin when contact happens instead of a ramp later.
A decelerating finger (a near-miss that stops short) predicts no contact; a pre-arm not followed by
contact within ``prearm_timeout_s`` is dropped and counted as false.

The stream is what the system knows of the finger (:func:`vishap.apps.cycle.contact_sample`): before
contact the tracked finger (the world's prediction, extrapolated to the tick), in contact the device
it drags; never the simulated finger itself.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from vishap.tactile.classifier import ContactState
from vishap.tactile.config import FeedForwardConfig
from vishap.tactile.contact import ContactSample

__all__ = ["Prediction", "ContactPredictor", "time_to_contact"]


@dataclass(frozen=True)
class Prediction:
    prearm: bool
    time_to_contact_s: float | None
    state: ContactState


def time_to_contact(h: float, v: float, a: float, horizon_s: float) -> float | None:
    """First τ ∈ [0, horizon] with h + v τ + a τ²/2 ≤ 0, or None."""
    if h <= 0.0:
        return 0.0
    if abs(a) < 1e-12:
        if v >= 0.0:
            return None
        tau = -h / v
        return tau if tau <= horizon_s else None
    disc = v * v - 2.0 * a * h
    if disc < 0.0:
        return None
    r = math.sqrt(disc)
    roots = sorted(x for x in ((-v - r) / a, (-v + r) / a) if x >= 0.0)
    return roots[0] if roots and roots[0] <= horizon_s else None


class ContactPredictor:
    """Pre-arm decision from the contact stream; counts pre-arms and false pre-arms."""

    def __init__(self, cfg: FeedForwardConfig, *, slip_speed_m_s: float = 0.15):
        self.cfg = cfg
        self.slip_speed = slip_speed_m_s
        self.reset()

    def reset(self) -> None:
        self.accel = 0.0
        self._last: ContactSample | None = None
        self.armed_since: float | None = None
        self.prearms = 0
        self.false_prearms = 0
        self._lockout = False  # after a false pre-arm, wait until the finger stops approaching

    def update(self, s: ContactSample, *, confirmed: bool = False) -> Prediction:
        """One sample; ``confirmed`` when the sleeve's sensor already reports contact.

        Between the touch reported by the contact stream and the sensor array's confirmation (the
        pressure needs a few ms to build) an existing pre-arm is held with τ = 0; it is never
        started then, so without feed-forward the onset stays purely sensor-triggered.
        """
        if self._last is not None:
            dt = s.t - self._last.t
            if dt > 0:
                raw = (s.velocity[2] - self._last.velocity[2]) / dt
                k = min(1.0, dt / self.cfg.accel_filter_s)
                self.accel += k * (raw - self.accel)
        self._last = s
        if confirmed or (s.in_contact and self.armed_since is None):
            self.armed_since = None
            self._lockout = False
            return Prediction(False, 0.0, ContactState.NONE)
        if s.in_contact:  # touching, not yet confirmed by the sensor: hold the pre-arm
            self._lockout = False
            if s.t - self.armed_since > self.cfg.prearm_timeout_s:
                self.armed_since = None
                return Prediction(False, 0.0, ContactState.NONE)
            state = ContactState.SLIP if s.tangential_speed > self.slip_speed else ContactState.CONCENTRATED
            return Prediction(True, 0.0, state)
        if not self.cfg.enabled:
            return Prediction(False, None, ContactState.NONE)
        h, v = float(s.position[2]), float(s.velocity[2])
        if self._lockout and v >= 0.0:
            self._lockout = False
        tau = None
        if -v >= self.cfg.min_approach_speed_m_s and not self._lockout:
            tau = time_to_contact(h, v, self.accel, self.cfg.horizon_s)
        if tau is not None:
            if self.armed_since is None:
                self.armed_since = s.t
                self.prearms += 1
            if s.t - self.armed_since > self.cfg.prearm_timeout_s:
                tau = None
                self._lockout = True
        if tau is None:
            if self.armed_since is not None:
                self.false_prearms += 1
                self.armed_since = None
            return Prediction(False, None, ContactState.NONE)
        state = ContactState.SLIP if s.tangential_speed > self.slip_speed else ContactState.CONCENTRATED
        return Prediction(True, tau, state)
