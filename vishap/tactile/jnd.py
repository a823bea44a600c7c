"""JND quantiser: suppress imperceptible changes of the band targets (PHSM §2.1, §2.2).

Each band has a Weber fraction for amplitude and for frequency (``bands[*].weber_*`` in the
config). A new target is sent to the actuators only when it differs from the last *sent* one by
at least one just-noticeable difference — |ΔA| ≥ w_A·max(A_sent, A_det) or |Δf| ≥ w_f·f_sent — or
when it crosses the band's detection threshold (switching on/off). Otherwise the previous command
stands. ``offered`` counts targets (one per band per tick), ``changed`` those that differ at all from
the previous offer, ``sent`` the commands that go out: the saving is ``1 − sent/offered`` against
streaming every tick and ``1 − sent/changed`` against a change-only sender.
"""
from __future__ import annotations

import numpy as np

from vishap.tactile.config import BandConfig

__all__ = ["JNDQuantiser", "jnd_changed"]


def jnd_changed(a_new: float, f_new: float, a_old: float, f_old: float, band: BandConfig) -> bool:
    """Whether (a_new, f_new) is perceptibly different from (a_old, f_old) in ``band``."""
    det = band.detection_threshold
    on_new, on_old = a_new >= det, a_old >= det
    if on_new != on_old:
        return True
    if not on_new:
        return False
    if abs(a_new - a_old) >= band.weber_amplitude * max(a_old, det):
        return True
    return abs(f_new - f_old) >= band.weber_frequency * max(f_old, 1e-9)


class JNDQuantiser:
    """Holds the last sent (amplitude, frequency) per band."""

    def __init__(self, bands: list[BandConfig]):
        self.bands = bands
        self.reset()

    def reset(self) -> None:
        n = len(self.bands)
        self.amplitude = np.zeros(n)
        self.frequency = np.array([max(b.low_hz, 1.0) for b in self.bands])
        self.offered = 0
        self.changed = 0  # offers that differ at all from the previous offer (a change-only sender's updates)
        self.sent = 0
        self._last_offer = np.full((len(self.bands), 2), np.nan)
        self._offer = None

    @property
    def saved_fraction(self) -> float:
        """Updates saved against sending every offer (one per band per control tick)."""
        return 1.0 - self.sent / self.offered if self.offered else 0.0

    @property
    def saved_vs_change_only(self) -> float:
        """Updates saved against sending every offer that changed at all."""
        return 1.0 - self.sent / self.changed if self.changed else 0.0

    def update(self, amplitudes, frequencies) -> np.ndarray:
        """Offer new per-band targets; return a bool mask of the bands whose command changed."""
        changed = np.zeros(len(self.bands), dtype=bool)
        offer = (tuple(amplitudes), tuple(frequencies))
        if offer == self._offer:  # the same targets again: nothing can have become perceptible
            self.offered += len(self.bands)
            return changed
        self._offer = offer
        for i, b in enumerate(self.bands):
            a, f = float(amplitudes[i]), float(frequencies[i])
            self.offered += 1
            last = self._last_offer[i]
            if not (last[0] == a and last[1] == f):
                self.changed += 1
                last[0], last[1] = a, f
            if jnd_changed(a, f, self.amplitude[i], self.frequency[i], b):
                self.amplitude[i] = a if a >= b.detection_threshold else 0.0
                self.frequency[i] = f
                self.sent += 1
                changed[i] = True
        return changed
