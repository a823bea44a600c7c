"""Finger motion prediction for the encountered-type meeting (VisHap §2.1 tracking, §2.2 world).

The world must hold the device *ahead* of the finger: the finger is seen at 20–60 Hz with tens of
milliseconds of latency, so its position "now" and where it will touch a surface are predicted.
VisHap tracks the fingertip with a constant-velocity Kalman filter; :class:`KalmanPredictor` is that
filter in 3-D (filterpy style: public ``x``, ``P``, ``Q``, ``R``; ``predict(dt)`` / ``update(z)``,
``update(None)`` for a missed frame). Two simpler peers share its interface for comparison:
:class:`LastSample` (no prediction) and :class:`FiniteDifference` (velocity from the last two samples).

Every predictor offers ``observe(t, p_robot)`` and ``state_at(t) -> (p, v)`` (extrapolated to
time ``t``, so latency is compensated by asking for the present), and :func:`contact_point`
intersects the predicted straight-line motion with a surface.
"""
from __future__ import annotations

import numpy as np

from vishap._core.motion import min_jerk, min_jerk_rate

__all__ = ["LastSample", "FiniteDifference", "KalmanPredictor", "MeetingPoint", "PathExtrapolator", "ReachFit", "make_predictor",
           "near_predictor", "measurement_std_m", "contact_point", "PREDICTORS", "NEAR_ACCEL_STD_M_S2"]


class LastSample:
    """No prediction: the last measured position, zero velocity."""

    name = "none"

    def __init__(self):
        self.t: float | None = None
        self.p = np.zeros(3)

    def reset(self) -> None:
        self.t = None

    @property
    def ready(self) -> bool:
        return self.t is not None

    def observe(self, t: float, p_robot) -> None:
        if p_robot is not None:
            self.t, self.p = float(t), np.asarray(p_robot, dtype=float).copy()

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.p.copy(), np.zeros(3)


class FiniteDifference(LastSample):
    """Constant velocity from the last two samples (no filtering)."""

    name = "cv"

    def __init__(self):
        super().__init__()
        self.v = np.zeros(3)

    def observe(self, t: float, p_robot) -> None:
        if p_robot is None:
            return
        p = np.asarray(p_robot, dtype=float)
        if self.t is not None and t > self.t:
            self.v = (p - self.p) / (t - self.t)
        self.t, self.p = float(t), p.copy()

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        dt = 0.0 if self.t is None else t - self.t
        return self.p + self.v * dt, self.v.copy()


class KalmanPredictor:
    """Constant-velocity Kalman filter on (p, v) in 3-D, white-acceleration process noise.

    Parameters
    ----------
    accel_std_m_s2:
        Standard deviation of the unmodelled acceleration (m/s²); larger follows turns faster.
    meas_std_m:
        Standard deviation of one fingertip measurement (m).
    """

    name = "kalman"

    def __init__(self, *, accel_std_m_s2: float = 2.0, meas_std_m: float = 0.0008):
        self.q = float(accel_std_m_s2) ** 2
        self.R = np.eye(3) * float(meas_std_m) ** 2
        self.H = np.hstack([np.eye(3), np.zeros((3, 3))])
        self.reset()

    def reset(self) -> None:
        self.x = np.zeros(6)
        self.P = np.diag([1.0] * 3 + [1.0] * 3)
        self.t: float | None = None
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()

    @property
    def ready(self) -> bool:
        return self.t is not None

    def _FQ(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        F = np.eye(6)
        F[:3, 3:] = np.eye(3) * dt
        q = self.q
        Q = np.zeros((6, 6))
        Q[:3, :3] = np.eye(3) * q * dt**4 / 4
        Q[:3, 3:] = Q[3:, :3] = np.eye(3) * q * dt**3 / 2
        Q[3:, 3:] = np.eye(3) * q * dt**2
        return F, Q

    def predict(self, dt: float) -> None:
        F, Q = self._FQ(dt)
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + Q
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()

    def update(self, z) -> None:
        """Fuse one measurement ``z`` (3,); ``None`` for a missed frame (keeps the prior)."""
        if z is None:
            return
        y = np.asarray(z, dtype=float) - self.H @ self.x
        S = self.H @ self.P @ self.H.T + self.R
        K = np.linalg.solve(S, self.H @ self.P).T
        self.x = self.x + K @ y
        self.P = (np.eye(6) - K @ self.H) @ self.P

    def observe(self, t: float, p_robot) -> None:
        p = None if p_robot is None else np.asarray(p_robot, dtype=float)
        if self.t is None:
            if p is None:
                return
            self.x[:3], self.x[3:] = p, 0.0
            self.P = np.diag([self.R[0, 0]] * 3 + [0.25] * 3)
            self.t = float(t)
            return
        if t > self.t:
            self.predict(t - self.t)
            self.t = float(t)
        self.update(p)

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        dt = 0.0 if self.t is None else t - self.t
        return self.x[:3] + self.x[3:] * dt, self.x[3:].copy()

    def cov_at(self, t: float) -> np.ndarray:
        """Covariance (6, 6) of the state extrapolated to ``t``."""
        dt = 0.0 if self.t is None else max(t - self.t, 0.0)
        F, Q = self._FQ(dt)
        return F @ self.P @ F.T + Q


class MeetingPoint:
    """Fuses successive predictions of where the finger will touch the surface (a static Kalman
    filter on a point, with process noise), each weighted by its uncertainty: position and velocity
    variance of the finger state and the unmodelled curvature ``0.5·a·τ²`` over the look-ahead τ.
    Early, far predictions count little; late, close ones count most.
    """

    def __init__(self, *, accel_m_s2: float = 0.5, drift_m: float = 0.002):
        self.a = float(accel_m_s2)
        self.q = float(drift_m) ** 2
        self.reset()

    def reset(self) -> None:
        self.c: np.ndarray | None = None
        self.var = 0.0

    def update(self, c, tau: float | None, var_p: float, var_v: float) -> np.ndarray:
        """Fuse the prediction ``c`` (3,) made ``tau`` seconds ahead; returns the fused point."""
        c = np.asarray(c, dtype=float)
        tau = 0.0 if tau is None else float(tau)
        r = var_p + tau * tau * var_v + (0.5 * self.a * tau * tau) ** 2
        if self.c is None:
            self.c, self.var = c.copy(), r
            return self.c.copy()
        self.var += self.q
        g = self.var / (self.var + r)
        self.c = self.c + g * (c - self.c)
        self.var *= 1.0 - g
        return self.c.copy()


class _SampleWindow:
    """The finger samples ``(t, p_robot)`` of the last ``window_s`` seconds (None samples are skipped)."""

    window_s: float
    samples: list
    meas_std: float
    #: a sample further than this many σ from the median of its neighbours is a false detection
    outlier_sigmas = 5.0

    def observe(self, t: float, p_robot) -> None:
        if p_robot is None:
            return
        self.samples.append((float(t), np.asarray(p_robot, dtype=float).copy()))
        while self.samples and self.samples[0][0] < t - self.window_s:
            self.samples.pop(0)

    def consistent(self) -> list:
        """The samples without those that stand out of their neighbours: further than
        ``outlier_sigmas`` σ from the per-axis median of the (up to) five centred on them — the first
        sample from the median of the first three, with the step between the next two allowed too. A finger's path is smooth, so on a
        monotone stretch that median is the sample itself; a false detection (the back of the hand,
        a knuckle) lies centimetres off it. The newest sample is always kept."""
        n = len(self.samples)
        if n < 3:
            return list(self.samples)
        P = np.array([p for _, p in self.samples])
        tol = self.outlier_sigmas * self.meas_std
        keep = np.ones(n, bool)
        for i in range(n - 1):
            k = min(2, i, n - 1 - i)  # neighbours on each side: the median of a monotone run is the sample
            lo, hi, allow = i - k, i + k + 1, 0.0
            if i == 0:
                lo, hi, allow = 0, 3, float(np.linalg.norm(P[2] - P[1]))
            keep[i] = np.linalg.norm(P[i] - np.median(P[lo:hi], axis=0)) <= tol + allow
        return [s for s, k in zip(self.samples, keep) if k]


class PathExtrapolator(_SampleWindow):
    """Where the finger's *path* meets a surface: the recent raw samples' tangential coordinates
    fitted as a quadratic in their height above the surface and evaluated at height 0. Its variance
    is the measurement noise through the fit's leverage plus ``(model_error · h)²`` for the height
    ``h`` still to be covered (the path may still bend).

    The path's shape does not depend on timing, so latency and the finger's deceleration do not
    bias it, and a bowed reach is followed. Returns the point and its variance from the fit's
    leverage and the measurement noise, or None with too few samples or too little descent.
    """

    def __init__(self, *, window_s: float = 0.4, meas_std_m: float = 0.0008, min_span_m: float = 0.006,
                 model_error: float = 0.1):
        self.window_s = float(window_s)
        self.model_error = float(model_error)
        self.meas_std = float(meas_std_m)
        self.var_meas = self.meas_std ** 2
        self.min_span = float(min_span_m)
        self.reset()

    def reset(self) -> None:
        self.samples: list[tuple[float, np.ndarray]] = []

    def contact(self, centre, R_robot_obj) -> tuple[np.ndarray, float] | None:
        samples = self.consistent()
        if len(samples) < 4:
            return None
        q = (np.array([p for _, p in samples]) - centre) @ R_robot_obj
        h = q[:, 2]
        if h[-1] <= 0 or h[0] - h[-1] < self.min_span or np.any(np.diff(h) > 0.002):
            return None  # not descending steadily towards the surface
        deg = 2 if len(h) >= 6 and h.max() - h.min() > 2 * self.min_span else 1
        X = np.vander(h, deg + 1)
        coef, *_ = np.linalg.lstsq(X, q[:, :2], rcond=None)
        lev = float(np.linalg.inv(X.T @ X)[-1, -1])
        uv = coef[-1]
        if np.hypot(*(uv - q[-1, :2])) > max(2.0 * h[-1], 0.005):
            return None  # implausible: further sideways than twice the height still to cover
        # noise through the fit's leverage, plus a model error growing with the height still to cover
        var = self.var_meas * lev + (self.model_error * h[-1]) ** 2
        return centre + R_robot_obj[:, 0] * uv[0] + R_robot_obj[:, 1] * uv[1], var


PREDICTORS = {"none": LastSample, "cv": FiniteDifference, "kalman": KalmanPredictor}


def make_predictor(name: str, **kwargs):
    """A predictor by name: ``none``, ``cv`` or ``kalman``."""
    try:
        return PREDICTORS[name](**kwargs)
    except KeyError:
        raise ValueError(f"unknown predictor {name!r}; expected one of {sorted(PREDICTORS)}") from None


#: the white-acceleration σ (m/s²) of :func:`near_predictor`'s filter. The world's filter (2 m/s² against
#: the demos' 3.6 mm stereo σ) let its velocity lag a reach starting from rest by 0.14 m/s 130 ms in
#: (wall demo seed 1's second approach: −0.17 against −0.31 m/s), putting the finger 40 ms ahead 10–14 mm
#: further from the device than it was; at 15 the lag is ≈ 0.03 m/s there (docs/robot.md, "speed near the finger")
NEAR_ACCEL_STD_M_S2 = 15.0


def near_predictor(predictor) -> KalmanPredictor:
    """The finger estimate the device's speed caps near the finger use beside the world's: a
    constant-velocity Kalman filter with the same measurement noise as ``predictor`` (its ``R``;
    the default without one) whose process noise (:data:`NEAR_ACCEL_STD_M_S2`) lets its velocity follow
    a reach from rest. The world's smoother filter serves the meeting point, whose landing it was
    tuned for; its velocity lags a starting reach by 100 ms, so the finger it extrapolates is too far.
    The caps take whichever of the two puts the finger nearer the device: this one is noisier, and
    its noise can only slow the device, never speed it up near the finger."""
    sigma = measurement_std_m(predictor)
    if sigma is None:
        return KalmanPredictor(accel_std_m_s2=NEAR_ACCEL_STD_M_S2)
    return KalmanPredictor(accel_std_m_s2=NEAR_ACCEL_STD_M_S2, meas_std_m=sigma)


def measurement_std_m(predictor) -> float | None:
    """The per-axis σ (m) of one fingertip sample that ``predictor`` assumes (its measurement noise
    ``R``), or None when it has none."""
    R = getattr(predictor, "R", None)
    return None if R is None else float(np.sqrt(np.trace(np.asarray(R, float)) / 3.0))


def contact_point(p_robot, v_robot, normal, offset_m: float, *, horizon_s: float, min_speed_m_s: float = 0.02):
    """Where the straight-line motion ``p + v·τ`` meets the plane ``n·x = d`` within ``horizon_s``.

    Returns ``(point on the plane, τ)``; when the finger is not approaching (normal speed below
    ``min_speed_m_s``) or would arrive later than the horizon, the motion is followed for at most
    the horizon and projected along the normal (τ = None).
    """
    p = np.asarray(p_robot, dtype=float)
    v = np.asarray(v_robot, dtype=float)
    n = np.asarray(normal, dtype=float)
    h = float(n @ p - offset_m)
    if h <= 0.0:  # already at or under the surface: its projection
        return p - n * h, 0.0
    closing = -float(n @ v)
    tau = None
    if closing > min_speed_m_s and h > 0:
        tau = h / closing
        if tau > horizon_s:
            tau = None
    q = p + v * (tau if tau is not None else (horizon_s if closing > min_speed_m_s else 0.0))
    return q - n * (float(n @ q) - offset_m), tau


_TAU_TABLE = np.linspace(0.0, 1.0, 1001)
_M_TABLE = min_jerk(_TAU_TABLE)


class ReachFit(_SampleWindow):
    """Where a reaching finger will touch a surface: a minimum-jerk reach (Flash & Hogan) fitted to
    the recent raw samples, in the surface's frame.

    Model, with the phase ``m = 10τ³ − 15τ⁴ + 6τ⁵`` of ``τ = (t − t0)/T`` clipped to [0, 1]:
    height ``h = h_S·(1 − m) + h_E·m``; tangential ``u = a + b·m + c·4m(1 − m)`` (a reach bowed
    sideways by ``c`` at mid-way; the tangential extent ``b`` has the prior ``N(0, reach_std_m²)``). The reach is assumed to end on the surface: ``h_E`` has the prior
    ``N(−end_depth_m, end_std_m²)``, which is what lets the onset (``h_S − h ∝ τ³``) tell the duration
    early; the bow ``c`` has the prior ``N(0, bow_std_m²)``. For each ``(t0, T)`` of a grid the linear
    parameters are a weighted least-squares fit; the grid is then weighted by ``exp(−χ²/2)`` and the
    touch point (where ``h`` crosses 0, or the end of the reach if it stays above) is averaged over
    it: the mean and its variance (the spread over the grid plus the fit's own variance) come back.

    A decelerating reach is modelled, so the touch point does not overshoot as a straight-line
    extrapolation does. Returns None with too few samples.
    """

    def __init__(self, *, window_s: float = 1.0, meas_std_m: float = 0.0008, end_depth_m: float = 0.0015,
                 end_std_m: float = 0.003, bow_std_m: float = 0.01, reach_std_m: float = 0.05, durations_s=None,
                 t0_step_s: float = 0.01, max_samples: int = 40):
        self.window_s = float(window_s)
        self.meas_std = float(meas_std_m)
        self.w = 1.0 / self.meas_std ** 2
        self.end_depth, self.w_end = float(end_depth_m), 1.0 / float(end_std_m) ** 2
        self.w_bow = 1.0 / float(bow_std_m) ** 2
        self.w_reach = 1.0 / float(reach_std_m) ** 2
        self.T = np.geomspace(0.1, 1.6, 40) if durations_s is None else np.asarray(durations_s, dtype=float)
        self.t0_step = float(t0_step_s)
        self.max_samples = int(max_samples)
        self.reset()

    def reset(self) -> None:
        self.samples: list[tuple[float, np.ndarray]] = []
        self.t_touch: float | None = None
        self._fit = None  # the weighted grid of the last fit: (t0, T, tangential coefficients, weights, R)

    def tangential_at(self, t: float) -> np.ndarray | None:
        """The fitted reach's tangential position (robot frame, m, relative to the fit's surface
        centre) at time ``t``, averaged over the grid (None before a fit)."""
        if self._fit is None:
            return None
        t0, TT, coef, pw, R = self._fit
        m = min_jerk((t - t0) / TT)
        uv = pw @ (coef[:, 0, :] + coef[:, 1, :] * m[:, None] + coef[:, 2, :] * (4.0 * m * (1.0 - m))[:, None])
        return R[:, 0] * uv[0] + R[:, 1] * uv[1]

    def tangential_velocity_at(self, t: float) -> np.ndarray | None:
        """The fitted reach's tangential velocity (robot frame, m/s) at time ``t``, averaged over the
        grid as the touch point is (None before a fit). A decelerating reach is modelled, so near the
        end it is not the straight-line estimate's, which lags the deceleration by the latency."""
        if self._fit is None:
            return None
        t0, TT, coef, pw, R = self._fit
        s = (t - t0) / TT
        m = min_jerk(s)
        dm = min_jerk_rate(s) / TT
        du = (coef[:, 1, :] + coef[:, 2, :] * (4.0 - 8.0 * m)[:, None]) * dm[:, None]
        uv = pw @ du
        return R[:, 0] * uv[0] + R[:, 1] * uv[1]

    def contact(self, centre, R_robot_obj) -> tuple[np.ndarray, float] | None:
        """(touch point on the surface plane (robot frame), variance m²) or None; sets ``t_touch``.

        Samples that stand out of their neighbours (:meth:`consistent`: a false detection, vision's
        first frame of a hand or a knuckle) are left out, so that one of them cannot turn the reach into
        another."""
        self.t_touch = None
        self._fit = None
        samples = self.consistent()
        if len(samples) < 4:
            return None
        if len(samples) > self.max_samples:  # a fast camera: evenly spaced samples, the latest kept
            idx = np.round(np.linspace(0, len(samples) - 1, self.max_samples)).astype(int)
            samples = [samples[i] for i in idx]
        ts = np.array([t for t, _ in samples])
        q = (np.array([p for _, p in samples]) - np.asarray(centre, float)) @ R_robot_obj
        T0, TT, coef, pw, mt, mean, var = self._fit_grid(ts, q)
        tau = np.interp(mt, _M_TABLE, _TAU_TABLE)
        self.t_touch = float(pw @ (T0 + tau * TT))
        sel = pw > 1e-4 * pw.max()  # the candidates that carry the average
        self._fit = (T0[sel], TT[sel], coef[sel], pw[sel] / pw[sel].sum(), np.asarray(R_robot_obj, float))
        return centre + R_robot_obj[:, 0] * mean[0] + R_robot_obj[:, 1] * mean[1], var

    def _fit_grid(self, ts, q):
        """The weighted grid of reaches fitted to samples at ``ts`` (N,) with surface-frame coordinates
        ``q`` (N, 3): start times, durations, tangential coefficients, weights, touch phases, the touch
        point's mean and variance."""
        t_last = ts[-1]
        t0 = np.arange(t_last - self.window_s - 0.5, t_last + 1e-9, self.t0_step)
        T0, TT = np.meshgrid(t0, self.T, indexing="ij")
        T0, TT = T0.ravel(), TT.ravel()
        m = min_jerk((ts[None, :] - T0[:, None]) / TT[:, None])  # (K, N)
        w = self.w
        # Each fit is a regularised least-squares problem A x = b; its minimum is c − x·b (no residuals
        # formed). Height: h = hS (1 − m) + hE m, prior hE ~ N(−end_depth, end_std²).
        h = q[:, 2]
        sm, smm = m.sum(1), (m * m).sum(1)
        n = float(len(ts))
        a11 = w * (n - 2 * sm + smm) + 1e-6 * w  # keeps a reach ended before the window solvable
        a12 = w * (sm - smm)
        a22 = w * smm + self.w_end
        mh = m @ h
        b1 = w * (h.sum() - mh)
        b2 = w * mh - self.w_end * self.end_depth
        det = a11 * a22 - a12 * a12
        hS = (a22 * b1 - a12 * b2) / det
        hE = (a11 * b2 - a12 * b1) / det
        chi = w * float(h @ h) + self.w_end * self.end_depth**2 - (hS * b1 + hE * b2)
        # tangential: u = a + b m + c β, β = 4 m (1 − m), priors b ~ N(0, reach_std²), c ~ N(0, bow_std²)
        beta = 4.0 * (m - m * m)
        A = np.empty((len(T0), 3, 3))
        A[:, 0, 0] = w * n
        A[:, 0, 1] = A[:, 1, 0] = w * sm
        A[:, 0, 2] = A[:, 2, 0] = w * beta.sum(1)
        A[:, 1, 1] = w * smm + self.w_reach  # a candidate whose phase hardly moves cannot claim a long reach
        A[:, 1, 2] = A[:, 2, 1] = w * (m * beta).sum(1)
        A[:, 2, 2] = w * (beta * beta).sum(1) + self.w_bow
        uv_data = q[:, :2]
        B = np.stack([np.broadcast_to(w * uv_data.sum(0), (len(T0), 2)), w * (m @ uv_data), w * (beta @ uv_data)], axis=1)
        coef = np.linalg.solve(A, B)  # (K, 3, 2)
        chi += w * float((uv_data * uv_data).sum()) - (coef * B).sum((1, 2))
        # touch phase: h crosses 0, else the end of the reach
        mt = np.where((hE < 0.0) & (hS > 0.0), hS / np.maximum(hS - hE, 1e-12), 1.0)
        uv = coef[:, 0, :] + coef[:, 1, :] * mt[:, None] + coef[:, 2, :] * (4.0 * mt * (1.0 - mt))[:, None]
        pw = np.exp(-0.5 * (chi - chi.min()))
        pw /= pw.sum()
        mean = pw @ uv
        var = float(pw @ ((uv - mean) ** 2).sum(1)) / 2.0
        b = int(np.argmax(pw))
        Ainv = np.linalg.inv(A[b])
        xt = np.array([1.0, mt[b], 4.0 * mt[b] * (1.0 - mt[b])])
        var += float(xt @ Ainv @ xt)
        return T0, TT, coef, pw, mt, mean, var
