"""The target guard: what the device does when its input goes bad (issue 9, faults).

Runs inside the 1 kHz servo tick, so its decision takes effect within one servo cycle. Input is
the newest device target from the world (X_d in the robot frame, when it was made, the vision
confidence) and whether a camera-to-robot calibration is loaded. Output is the target the
controller may use and the action taken:

- ``track``   the input is fresh, finite, confident and calibrated: use it (clamped to the box);
- ``hold``    the input is stale, non-finite or the finger is lost: keep the last good target;
- ``retreat`` the trouble has lasted longer than ``retreat_after_s``, or there is no calibration:
              move to the retreat point, away from where a finger could be.

Each fault is counted once per episode (entering the fault), not once per tick.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

__all__ = ["Fault", "GuardDecision", "TargetGuard"]


class Fault(str, Enum):
    FINGER_LOST = "finger_lost"
    VISION_STALLED = "vision_stalled"
    NAN_INPUT = "nan_input"
    CALIBRATION_MISSING = "calibration_missing"
    FRAME_DROPPED = "frame_dropped"


@dataclass(frozen=True)
class GuardDecision:
    X_d: np.ndarray          # (3,) m, robot frame: always finite, inside the box
    action: str              # "track" | "hold" | "retreat"
    fault: Fault | None      # the active fault, if any


@dataclass
class TargetGuard:
    """Decides, each servo tick, which device target is safe to use."""

    box_lo: np.ndarray
    box_hi: np.ndarray
    retreat_point: np.ndarray
    stale_after_s: float = 0.15        # > 4 frames at 30 Hz without a new target
    retreat_after_s: float = 0.5
    min_confidence: float = 0.2
    counts: dict = field(default_factory=lambda: {f.value: 0 for f in Fault})

    def __post_init__(self):
        self.box_lo = np.asarray(self.box_lo, float).reshape(3)
        self.box_hi = np.asarray(self.box_hi, float).reshape(3)
        self.retreat_point = np.clip(np.asarray(self.retreat_point, float).reshape(3), self.box_lo, self.box_hi)
        if not (np.all(np.isfinite(self.box_lo)) and np.all(self.box_hi > self.box_lo)):
            raise ValueError("TargetGuard: the box needs finite lower corner below the upper corner")
        self._last_good = self.retreat_point.copy()
        self._active: Fault | None = None
        self._trouble_since: float | None = None

    def count(self, fault: Fault) -> None:
        """Count an event seen outside the guard (e.g. a dropped frame)."""
        self.counts[Fault(fault).value] += 1

    def _enter(self, fault: Fault, t: float) -> None:
        if self._active is not fault:
            self.counts[fault.value] += 1
            self._active = fault
        if self._trouble_since is None:
            self._trouble_since = t

    def decide(self, t: float, X_d, made_at: float, confidence: float, calibrated: bool = True) -> GuardDecision:
        """The target to use at time ``t`` given the newest input (see module docstring)."""
        fault = None
        if not calibrated:
            fault = Fault.CALIBRATION_MISSING
        else:
            x = np.asarray(X_d, dtype=float).reshape(-1)
            if x.shape[0] != 3 or not np.all(np.isfinite(x)) or not math.isfinite(made_at) or not math.isfinite(confidence):
                fault = Fault.NAN_INPUT
            elif t - made_at > self.stale_after_s:
                fault = Fault.VISION_STALLED
            elif confidence < self.min_confidence:
                fault = Fault.FINGER_LOST
        if fault is None:
            self._active = None
            self._trouble_since = None
            self._last_good = np.clip(x, self.box_lo, self.box_hi)
            return GuardDecision(self._last_good.copy(), "track", None)
        self._enter(fault, t)
        if fault is Fault.CALIBRATION_MISSING or t - self._trouble_since >= self.retreat_after_s:
            return GuardDecision(self.retreat_point.copy(), "retreat", fault)
        return GuardDecision(self._last_good.copy(), "hold", fault)
