"""The scripted finger of each demo: approach, touch, press, explore (slide/stroke), lift.

A script is data: a start point and a list of ``(duration_s, pad_point_robot)`` moves of the finger
*pad* (the lowest point of the fingertip's cap, the point that touches), joined by minimum-jerk
segments (smooth, zero velocity at each way-point). The first ``hidden_s`` seconds leave the hand
out of view (VisHap learns its background from the first 10 frames). The cap centre — what vision
locates and the renderer poses — is the pad point plus the cap radius along the surface normal.
The scripts touch each scene's object (``datasets/synthetic/scenes``: surfaces on z = −0.150 m)
and include one fast approach, so the device's lead time is tested at speed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap._core.motion import min_jerk, min_jerk_rate

__all__ = ["FingerScript", "Z", "script_for"]

Z = -0.150  # surface height of every demo object (m, robot frame)


@dataclass(frozen=True)
class FingerScript:
    start: tuple[float, float, float]
    moves: tuple[tuple[float, tuple[float, float, float]], ...]
    hidden_s: float = 0.0
    finger_dir: tuple[float, float, float] = (-0.766, 0.0, -0.643)
    flexion: float = 0.2
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self):
        object.__setattr__(self, "_t", np.concatenate([[0.0], np.cumsum([d for d, _ in self.moves])]) + self.hidden_s)
        object.__setattr__(self, "_p", np.array([self.start] + [p for _, p in self.moves], float))

    @property
    def duration_s(self) -> float:
        return float(self._t[-1])

    def pad(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Pad point (m) and velocity (m/s) at time ``t`` (held at the ends)."""
        T, P = self._t, self._p
        if t <= T[0]:
            return P[0].copy(), np.zeros(3)
        if t >= T[-1]:
            return P[-1].copy(), np.zeros(3)
        k = int(np.searchsorted(T, t, side="right") - 1)
        dur = T[k + 1] - T[k]
        tau = (t - T[k]) / dur
        s = float(min_jerk(tau))
        ds = float(min_jerk_rate(tau)) / dur
        d = P[k + 1] - P[k]
        return P[k] + s * d, ds * d

    def tip(self, t: float, tip_radius_m: float) -> np.ndarray:
        """Centre of the fingertip cap (what vision detects)."""
        return self.pad(t)[0] + tip_radius_m * np.asarray(self.normal, float)

    def visible(self, t: float) -> bool:
        return t >= self.hidden_s


def script_for(scene: str, *, hidden_s: float) -> FingerScript:
    """The scripted finger of demo ``scene`` (defined in :mod:`vishap.apps.<scene>`)."""
    from vishap.apps.demos import demo_module

    return demo_module(scene).script(hidden_s)
