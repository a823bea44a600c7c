"""The target guard: what the device does when its input goes bad (issue 9, faults).

Runs inside the 1 kHz servo tick, so its decision takes effect within one servo cycle. Input is
the newest device target from the world (X_d in the robot frame, when it was made, the vision
confidence, whether vision reported the finger lost), whether a camera-to-robot calibration is
loaded and whether the record carrying it was one a scene step could have written. Output is the
target the controller may use and the action taken:

- ``track``   the input is fresh, finite, confident and calibrated: use it (clamped to the box);
- ``hold``    the input is stale, non-finite, stamped later than now (a clock fault), the finger
              is lost or the record is corrupt: keep the last good target;
- ``retreat`` the trouble has lasted longer than ``retreat_after_s``, or there is no calibration:
              move to the retreat point, away from where a finger could be.

Vision says "lost" explicitly (no skin left where it searched, or a dropped track), and the guard
holds on the first servo tick that sees it; the confidence floor catches a track that still coasts through missed
frames (four at 30 Hz, about 117 ms). Holding on every missed frame was measured to park the
device where it hides the fingertip from a camera (docs/runtime.md), so a single miss is not a loss.

A finger that vision loses while it presses the device is not gone: the device feels it (the
caller says so with ``pressed``: the device pushed in under the subject's surface while the law
renders it). Vision loses a pressing fingertip routinely — the hand, the device's own links or the
object hide it — and retreating then would pull the surface from under the finger. So while
``pressed`` and the fault is a lost finger, the guard holds and its retreat timer starts only when
the device is let go. A stalled vision process, a non-finite target or a missing calibration are
faults of the system itself and keep their timers.

Each fault is counted once per episode (entering the fault), not once per tick.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["Fault", "GuardDecision", "TargetGuard", "record_values_valid"]


class Fault(str, Enum):
    FINGER_LOST = "finger_lost"
    VISION_STALLED = "vision_stalled"
    NAN_INPUT = "nan_input"
    CALIBRATION_MISSING = "calibration_missing"
    FRAME_DROPPED = "frame_dropped"
    FUTURE_STAMP = "future_stamp"      # a target made later than the servo's now: clocks disagree
    BAD_RECORD = "bad_record"          # a record no scene step writes (all zero, a counter that is not a count)


def record_values_valid(seq: float, flags, subject: float, n_subjects: int | None = None) -> bool:
    """Whether a target record's counter, flags and subject are values a scene step writes.

    The scene step counts its records from 1, so a record that reads 0 (an all-zero block: a
    producer that wrote nothing real, or memory cleared under the reader) is not one, and neither is
    a counter or subject that is NaN, fractional or out of range, or a flag other than 0 or 1. The
    channel's own sequence number says whether anything was written at all; this says whether what
    was written can be trusted.
    """
    if not (1.0 <= seq <= 2.0**53 and seq == math.floor(seq)):
        return False
    if not all(f == 0.0 or f == 1.0 for f in flags):
        return False
    hi = math.inf if n_subjects is None else n_subjects - 1
    return -1.0 <= subject <= hi and subject == math.floor(subject)


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
        retreat = np.asarray(self.retreat_point, float).reshape(3)
        if not np.all(np.isfinite(retreat)):
            raise ConfigError(f"TargetGuard: retreat point {retreat.tolist()} is not finite", field="retreat_point")
        if not (np.all(np.isfinite(self.box_lo)) and np.all(np.isfinite(self.box_hi)) and np.all(self.box_hi > self.box_lo)):
            raise ConfigError("TargetGuard: the box needs finite corners, the lower below the upper", field="box")
        self.retreat_point = np.clip(retreat, self.box_lo, self.box_hi)
        for name, lo, hi in (("stale_after_s", 0.0, math.inf), ("retreat_after_s", 0.0, math.inf),
                             ("min_confidence", 0.0, 1.0)):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ConfigError(f"TargetGuard: {name} = {v!r}, expected a finite value in [{lo}, {hi}]", field=name)
        self._lo = tuple(float(v) for v in self.box_lo)
        self._hi = tuple(float(v) for v in self.box_hi)
        self._retreat = tuple(float(v) for v in self.retreat_point)
        self.reset()

    def reset(self) -> None:
        """Forget the last good target and any fault in progress (the counts stay)."""
        self._good = list(self._retreat)  # last good target (before any input: the retreat point)
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

    def decide(self, t: float, X_d, made_at: float, confidence: float, calibrated: bool = True,
               pressed: bool = False, *, lost: bool = False, valid: bool = True) -> GuardDecision:
        """The target to use at time ``t`` given the newest input (see module docstring).

        ``lost``: vision reported the finger lost in this input; ``valid``: false for a record no
        scene step could have written (its content is then ignored)."""
        x = np.asarray(X_d, dtype=float).reshape(-1)
        if x.shape[0] != 3:
            x = np.full(3, np.nan)
        gx, gy, gz, action, fault = self.decide_scalar(
            t, float(x[0]), float(x[1]), float(x[2]), float(made_at), float(confidence), calibrated, pressed,
            lost, valid,
        )
        return GuardDecision(np.array((gx, gy, gz)), action, fault)

    def decide_scalar(self, t, x, y, z, made_at, confidence, calibrated=True, pressed=False, lost=False, valid=True):
        """:meth:`decide` on plain floats for the 1 kHz hot path: ``(x, y, z, action, fault)``.

        The order of the tests matters: a corrupt record says nothing; a stale, future-stamped or
        unstamped input is a fault of the system (its retreat timer runs even while the device is
        pressed), checked before the finger's own state, so that a lost finger cannot hide a
        stalled vision process."""
        isfinite = math.isfinite
        if not valid:
            fault = Fault.BAD_RECORD
        elif not calibrated:
            fault = Fault.CALIBRATION_MISSING
        elif not isfinite(made_at):
            fault = Fault.NAN_INPUT
        elif made_at > t:
            fault = Fault.FUTURE_STAMP
        elif t - made_at > self.stale_after_s:
            fault = Fault.VISION_STALLED
        elif lost:
            fault = Fault.FINGER_LOST
        elif not (isfinite(x) and isfinite(y) and isfinite(z) and isfinite(confidence)):
            fault = Fault.NAN_INPUT
        elif confidence < self.min_confidence:
            fault = Fault.FINGER_LOST
        else:
            lo, hi = self._lo, self._hi
            g = self._good
            g[0] = lo[0] if x < lo[0] else hi[0] if x > hi[0] else x
            g[1] = lo[1] if y < lo[1] else hi[1] if y > hi[1] else y
            g[2] = lo[2] if z < lo[2] else hi[2] if z > hi[2] else z
            self._active = None
            self._trouble_since = None
            return g[0], g[1], g[2], "track", None
        self._enter(fault, t)
        if pressed and fault is Fault.FINGER_LOST:  # the device feels the finger: its timer waits for the release
            self._trouble_since = t
        if fault is Fault.CALIBRATION_MISSING or t - self._trouble_since >= self.retreat_after_s:
            r = self._retreat
            return r[0], r[1], r[2], "retreat", fault
        g = self._good
        return g[0], g[1], g[2], "hold", fault
