"""Constant-velocity Kalman tracking of the fingertip (VisHap §2.1, last paragraph).

"We assume that the fingertip moves approximately at a constant velocity and in a straight line.
We search for the fingertip in a small window around the predicted position."

:class:`KalmanCV` is a plain constant-velocity Kalman filter in ``d`` dimensions (image: d = 2)
whose state is public, as in filterpy: ``x`` (position then velocity), ``P``, ``F``, ``Q``, ``H``,
``R``, the prior (``x_prior``, ``P_prior``) and the posterior (``x_post``, ``P_post``) — kept by
reference: each step replaces ``x`` and ``P`` with new arrays and never writes into them;
``predict(dt)``; ``update(z)``; ``update(None)`` records a miss. :class:`TipTracker` adds the
search window around the prediction, a confidence that drops with consecutive misses, and the
"lost" state after which the caller re-detects over the full frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vishap._core.errors import ShapeError

__all__ = ["KalmanCV", "TrackerConfig", "TipTracker"]


_MAX_STEPS_KEPT = 64  # (dt, q) pairs whose F and Q a filter keeps


class KalmanCV:
    """Constant-velocity Kalman filter; white-noise acceleration of spectral density ``q``.

    Parameters
    ----------
    dim: number of position coordinates ``d`` (state has ``2d`` entries).
    q: acceleration noise spectral density (units²/s³, e.g. px²/s³).
    r: measurement noise variance (units², e.g. px²).

    ``F`` and ``Q`` follow from the step ``dt`` and ``q`` (assign ``q`` to change the noise): each
    predict takes them from the pairs made for earlier steps of the same ``dt`` (a frame interval, a
    difference of two frame times, takes a few float values over a sequence) or makes them anew.
    """

    def __init__(self, dim: int = 2, *, q: float = 1e5, r: float = 0.25, p0_pos: float = 4.0, p0_vel: float = 1e4):
        self.dim = d = int(dim)
        self.q = float(q)
        self.x = np.zeros(2 * d)
        self.P = np.diag(np.r_[np.full(d, p0_pos), np.full(d, p0_vel)])
        self.F = np.eye(2 * d)
        self.Q = np.zeros((2 * d, 2 * d))
        self.H = np.hstack([np.eye(d), np.zeros((d, d))])
        self.R = np.eye(d) * float(r)
        self._p0 = (p0_pos, p0_vel)
        self.x_prior, self.P_prior = self.x, self.P
        self.x_post, self.P_post = self.x, self.P
        self.y = np.zeros(d)       # last innovation
        self.S = np.eye(d)         # last innovation covariance
        self.misses = 0            # consecutive update(None) calls
        self.initialized = False
        self._dt = self._q = None   # the step and noise F and Q were made for
        self._FQ: dict = {}         # (dt, q) → (F, Q): a frame interval recurs (the same float) every few frames
        self._I = np.eye(2 * d)

    def _transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """``F`` and ``Q`` for a step of ``dt`` seconds (new arrays: a step never writes into them)."""
        key = (dt, self.q)
        FQ = self._FQ.get(key)
        if FQ is None:
            if len(self._FQ) >= _MAX_STEPS_KEPT:
                self._FQ.clear()
            d, q = self.dim, self.q
            F, Q = np.eye(2 * d), np.zeros((2 * d, 2 * d))
            q3, q2, q1 = q * dt ** 3 / 3, q * dt ** 2 / 2, q * dt
            for i in range(d):
                F[i, i + d] = dt
                Q[i, i] = q3
                Q[i, i + d] = Q[i + d, i] = q2
                Q[i + d, i + d] = q1
            F.flags.writeable = Q.flags.writeable = False  # kept and shared by later steps: never written into
            FQ = self._FQ[key] = F, Q
        return FQ

    def reset(self, z) -> None:
        """Start at position ``z`` with zero velocity and the initial covariance."""
        d = self.dim
        z = np.asarray(z, dtype=np.float64).reshape(d)
        self.x = np.r_[z, np.zeros(d)]
        self.P = np.diag(np.r_[np.full(d, self._p0[0]), np.full(d, self._p0[1])])
        self.x_post, self.P_post = self.x, self.P
        self.misses = 0
        self.initialized = True

    def predict(self, dt: float) -> np.ndarray:
        """Propagate the state by ``dt`` seconds; returns the predicted position."""
        d = self.dim
        dt = float(dt)
        if not (dt >= 0.0 and dt < math.inf):
            raise ShapeError(f"dt: expected a finite time step ≥ 0 s, got {dt}")
        if dt != self._dt or self.q != self._q:
            self.F, self.Q = self._transition(dt)
            self._dt, self._q = dt, self.q
        self.x = self.F @ self.x
        self.P = self.F @ self.P @ self.F.T + self.Q
        self.x_prior, self.P_prior = self.x, self.P
        return self.x[:d]

    def update(self, z) -> None:
        """Correct with measurement ``z`` (d,), or record a miss with ``None`` (state = prior)."""
        if z is None:
            self.misses += 1
            self.x_post, self.P_post = self.x, self.P
            return
        d = self.dim
        z = np.asarray(z, dtype=np.float64).reshape(d)
        if not all(map(math.isfinite, z.tolist())):
            raise ShapeError("z: measurement contains NaN or inf")
        # H = [I 0]: H x, H P Hᵀ and P Hᵀ are slices
        self.y = z - self.x[:d]
        PHt = self.P[:, :d]
        self.S = S = PHt[:d] + self.R
        S_inv = _inverse(S) if d <= 2 else None
        K = PHt @ S_inv if S_inv is not None else np.linalg.solve(S, PHt.T).T
        self.x = self.x + K @ self.y
        I_KH = self._I.copy()
        I_KH[:, :d] -= K
        self.P = I_KH @ self.P @ I_KH.T + K @ self.R @ K.T  # Joseph form
        self.x_post, self.P_post = self.x, self.P
        self.misses = 0

    @property
    def position(self) -> np.ndarray:
        return self.x[: self.dim]

    @property
    def velocity(self) -> np.ndarray:
        return self.x[self.dim:]

    def mahalanobis(self, z) -> float:
        """Distance of ``z`` from the current (prior) prediction in innovation standard deviations."""
        y = np.asarray(z, dtype=np.float64) - self.H @ self.x
        S = self.H @ self.P @ self.H.T + self.R
        return float(np.sqrt(y @ np.linalg.solve(S, y)))


def _inverse(S: np.ndarray) -> np.ndarray | None:
    """Inverse of a 1×1 or 2×2 innovation covariance in closed form (a general solver's checks
    cost more than the arithmetic at this size); None when singular (the solver then says so)."""
    if S.shape[0] == 1:
        return 1.0 / S if S[0, 0] != 0 else None
    (a, b), (c, e) = S.tolist()
    det = a * e - b * c
    if det == 0 or not math.isfinite(det):
        return None
    return np.array([[e / det, -b / det], [-c / det, a / det]])


@dataclass(frozen=True)
class TrackerConfig:
    q_px: float = 2e4             # acceleration noise, px²/s³ (measured: 2e5 noisier, 5e2 lags)
    r_px: float = 0.25            # measurement variance, px²
    window_sigma: float = 4.0     # search half-width = window_sigma·σ_pos + margin
    window_margin_px: float = 12.0
    window_max_px: float = 80.0   # a window wider than this is not worth it: re-detect full frame
    max_misses: int = 5           # consecutive misses before the track is lost
    confidence_decay: float = 0.6  # confidence after k misses = decay**k


class TipTracker:
    """One camera's 2-D fingertip track: Kalman prediction, search window, misses, loss."""

    def __init__(self, config: TrackerConfig = TrackerConfig()):
        self.config = config
        self.kf = KalmanCV(2, q=config.q_px, r=config.r_px)
        self.t: float | None = None
        self.t_hit: float | None = None  # time of the last detection
        self.t_start: float | None = None  # time the current track began (a reset starts a new one)

    @property
    def tracking(self) -> bool:
        return self.kf.initialized and self.kf.misses <= self.config.max_misses

    @property
    def confidence(self) -> float:
        if not self.kf.initialized:
            return 0.0
        return float(self.config.confidence_decay ** self.kf.misses) if self.tracking else 0.0

    def predict(self, t: float) -> np.ndarray | None:
        """Predicted position at time ``t`` (None when not tracking)."""
        if not self.tracking:
            return None
        dt = 0.0 if self.t is None else max(0.0, t - self.t)
        self.t = t
        return self.kf.predict(dt).copy()

    def window(self, size: tuple[int, int], extra_px: float = 0.0):
        """Search window ``(x0, y0, x1, y1)`` around the prediction, or None to search the full frame."""
        if not self.tracking:
            return None
        c = self.config
        P = self.kf.P
        hx = c.window_sigma * math.sqrt(max(float(P[0, 0]), 0.0)) + c.window_margin_px + extra_px
        hy = c.window_sigma * math.sqrt(max(float(P[1, 1]), 0.0)) + c.window_margin_px + extra_px
        if hx > c.window_max_px or hy > c.window_max_px:
            return None
        u, v = self.kf.position.tolist()
        w, h = size
        x0, x1 = max(0, int(u - hx)), min(w, math.ceil(u + hx) + 1)
        y0, y1 = max(0, int(v - hy)), min(h, math.ceil(v + hy) + 1)
        if x1 <= x0 or y1 <= y0:
            return None
        return x0, y0, x1, y1

    def restart(self, t: float, uv) -> None:
        """Start a new track at ``uv`` (time ``t``)."""
        self.kf.reset(uv)
        self.t = self.t_hit = self.t_start = t

    def held_since(self, t: float) -> bool:
        """Has the current track held, without a restart, since time ``t``?"""
        return self.tracking and self.t_start is not None and self.t_start <= t

    def update(self, t: float, uv) -> None:
        """Feed a detection (or None for a miss) at time ``t``."""
        if uv is None:
            if self.kf.initialized:
                self.kf.update(None)
            return
        if not self.tracking:
            self.restart(t, uv)
            return
        self.t_hit = t
        if self.t is None:
            self.t = t
        self.kf.update(uv)
