"""The finger-sleeve strain-sensor array and its contact features (PHSM §2.3, §2.4, §3.1–3.4).

A grid of square elements covers the index-finger sleeve (x along the finger, y across it, metres
in the sleeve frame; the paper's region centres μ₁…μ₃ = 3.5, 5.0, 6.5 cm lie on the x axis). The
contact model is a Hertz patch: an elliptical footprint with semi-axes (a_x, a_y) carrying the
normal force F with pressure p(r) = p₀·√(1 − r²), p₀ = 3F / (2π a_x a_y); each element reports the
mean pressure over its area (integrated at ``subsamples²`` points) plus optional noise.

:class:`FeatureTracker` turns the frame stream into the quantities the classifier of §2.4 uses:
contact centroid, area (engaged elements × element area), engaged elements, total force, centroid
velocity (least-squares slope over a short window), force stability over the last 250 ms, and the
durations of local pressure pulses (how long each element stays engaged).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from vishap.tactile.config import SensorConfig

def _pair(v) -> tuple[float, float]:
    """A scalar or a 2-sequence as two floats."""
    if np.ndim(v) == 0:
        return float(v), float(v)
    return float(v[0]), float(v[1])


__all__ = ["SensorArray", "SensorFrame", "ContactFeatures", "FeatureTracker", "hertz_radius", "pad_patch"]


def hertz_radius(force_n: float, cfg: SensorConfig) -> float:
    """Patch radius of a Hertz contact, a ∝ F^(1/3), scaled to ``contact_radius_ref_m`` at ``force_ref_n``."""
    f = max(float(force_n), 0.0)
    return cfg.contact_radius_ref_m * (f / cfg.force_ref_n) ** (1.0 / 3.0)


def pad_patch(force_n: float, cfg: SensorConfig, finger_dir=None) -> tuple[np.ndarray, np.ndarray]:
    """Where and how large the patch on the sleeve is when the contact model does not say.

    Without the finger's direction: a Hertz patch at the fingertip centre. With ``finger_dir`` (3,),
    the finger's pointing direction in the object frame (z = surface normal), its pitch
    θ = asin(−dir_z) moves the patch from the fingertip (θ ≥ ``pitch_tip_rad``: pressing, §3.2) to
    the pad (θ ≤ ``pitch_flat_rad``: a flat finger stroking, §3.3), where it is longer and wider.
    Returns (centre (2,), semi-axes (2,)) in metres, sleeve frame.
    """
    a = hertz_radius(force_n, cfg)
    s = 1.0
    if finger_dir is not None:
        d = np.asarray(finger_dir, dtype=np.float64)
        n = float(np.linalg.norm(d))
        if n > 1e-9 and np.isfinite(n):
            pitch = math.asin(min(max(-d[2] / n, -1.0), 1.0))
            span = max(cfg.pitch_tip_rad - cfg.pitch_flat_rad, 1e-6)
            s = min(max((pitch - cfg.pitch_flat_rad) / span, 0.0), 1.0)  # 0 flat pad … 1 fingertip
    flat = 1.0 - s
    centre = np.array([cfg.default_pad_x_m * s + cfg.flat_pad_x_m * flat, 0.0])
    radius = np.array([a * (1.0 + cfg.flat_elongation * flat), a * (1.0 + cfg.flat_widening * flat)])
    return centre, radius


@dataclass(frozen=True)
class SensorFrame:
    """One reading of the array: ``pressure_pa`` (rows, cols) at time ``t``."""

    t: float
    pressure_pa: np.ndarray


class SensorArray:
    """Element geometry and the Hertz-patch contact model of the sleeve."""

    def __init__(self, cfg: SensorConfig):
        self.cfg = cfg
        xs = cfg.x0_m + cfg.pitch_m * np.arange(cfg.cols)
        ys = cfg.pitch_m * (np.arange(cfg.rows) - (cfg.rows - 1) / 2.0)
        self.y_m, self.x_m = np.meshgrid(ys, xs, indexing="ij")  # (rows, cols)
        self.element_area_m2 = cfg.pitch_m**2
        s = cfg.subsamples
        off = cfg.pitch_m * ((np.arange(s) + 0.5) / s - 0.5)
        oy, ox = np.meshgrid(off, off, indexing="ij")
        # integration points, (rows*cols, s*s)
        self._px = (self.x_m.reshape(-1, 1) + ox.reshape(1, -1))
        self._py = (self.y_m.reshape(-1, 1) + oy.reshape(1, -1))
        self._cache: dict[tuple[int, int, int, int], np.ndarray] = {}

    @property
    def shape(self) -> tuple[int, int]:
        return (self.cfg.rows, self.cfg.cols)

    def pressure(self, centre_m, radius_m, force_n: float) -> np.ndarray:
        """Noise-free element pressures (rows, cols), Pa, for a patch at ``centre_m`` (2,)
        with semi-axes ``radius_m`` (scalar or (2,)) carrying ``force_n``."""
        if force_n <= 0.0:
            return np.zeros(self.shape)
        return self.unit_pressure(centre_m, radius_m) * force_n

    def unit_pressure(self, centre_m, radius_m, *, quantum_m: float = 2e-5) -> np.ndarray:
        """Element pressures per newton (Pa/N); the geometry is snapped to ``quantum_m`` (20 µm) and
        cached, since for a fixed footprint the pressure scales exactly with the force."""
        ax, ay = _pair(radius_m)
        key = (round(float(centre_m[0]) / quantum_m), round(float(centre_m[1]) / quantum_m),
               round(max(ax, 1e-5) / quantum_m), round(max(ay, 1e-5) / quantum_m))
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        cx, cy, ax, ay = (k * quantum_m for k in key)
        ax, ay = max(ax, 1e-5), max(ay, 1e-5)
        out = np.zeros(self.cfg.rows * self.cfg.cols)
        force_n = 1.0
        # only elements near the patch need evaluating
        near = (np.abs(self.x_m.ravel() - cx) <= ax + self.cfg.pitch_m) & (
            np.abs(self.y_m.ravel() - cy) <= ay + self.cfg.pitch_m
        )
        if near.any():
            r2 = ((self._px[near] - cx) / ax) ** 2 + ((self._py[near] - cy) / ay) ** 2
            p0 = 3.0 * force_n / (2.0 * np.pi * ax * ay)
            out[near] = p0 * np.sqrt(np.clip(1.0 - r2, 0.0, None)).mean(axis=1)
        out = out.reshape(self.shape)
        out.flags.writeable = False
        if len(self._cache) >= 4096:
            self._cache.clear()
        self._cache[key] = out
        return out

    def frame(self, t: float, centre_m, radius_m, force_n: float, *, rng: np.random.Generator | None = None,
              noise_pa: float | None = None) -> SensorFrame:
        """A sensor reading with additive Gaussian noise (clipped at 0 Pa)."""
        p = self.pressure(centre_m, radius_m, force_n)
        sigma = self.cfg.noise_pa if noise_pa is None else noise_pa
        if rng is not None and sigma > 0:
            p = np.clip(p + rng.normal(0.0, sigma, p.shape), 0.0, None)
        return SensorFrame(float(t), p)


@dataclass
class ContactFeatures:
    """Features of the current contact (PHSM §2.4 / §3.1). Lengths in m, area in m², force in N."""

    t: float
    in_contact: bool
    total_force_n: float
    area_m2: float
    engaged: int
    centroid_m: np.ndarray
    peak_pa: float
    centroid_velocity_m_s: np.ndarray
    pulse_s: float
    force_cv: float
    broad_for_s: float

    @property
    def mean_pressure_pa(self) -> float:
        """Mean pressure over the engaged area (0 without contact)."""
        return self.total_force_n / self.area_m2 if self.area_m2 > 0 else 0.0

    @property
    def speed_m_s(self) -> float:
        v = self.centroid_velocity_m_s
        return math.hypot(v[0], v[1])


class FeatureTracker:
    """Streaming feature extraction from sensor frames (one call per frame, constant cost)."""

    def __init__(self, array: SensorArray, *, velocity_window_s: float = 0.02, stable_window_s: float = 0.25,
                 broad_area_m2: float = 1e-4, min_force_n: float = 0.05, pulse_memory_s: float = 0.15):
        self.array = array
        self.vw = velocity_window_s
        self.sw = stable_window_s
        self.broad_area = broad_area_m2
        self.min_force = min_force_n
        self.pulse_memory = pulse_memory_s
        thr = array.cfg.engage_pressure_pa
        self.on_pa, self.off_pa = thr, 0.6 * thr  # engagement hysteresis against noise flicker
        self.floor_pa = min(3.0 * array.cfg.noise_pa, 0.5 * thr)
        self.reset()

    @classmethod
    def from_config(cls, cfg, array: SensorArray | None = None) -> FeatureTracker:
        """A tracker with the windows and thresholds of a :class:`~vishap.tactile.config.TactileConfig`."""
        c = cfg.classifier
        return cls(array or SensorArray(cfg.sensor), velocity_window_s=c.velocity_window_s,
                   stable_window_s=c.stable_time_s, broad_area_m2=c.distributed_area_m2, min_force_n=c.min_force_n)

    def reset(self) -> None:
        n = self.array.cfg.rows * self.array.cfg.cols
        self._xr = np.ascontiguousarray(self.array.x_m.ravel())
        self._yr = np.ascontiguousarray(self.array.y_m.ravel())
        self._engaged = np.zeros(n, dtype=bool)
        self._onset = np.zeros(n)
        self._pulses: deque[tuple[float, float]] = deque()  # (end time, duration)
        # sliding windows with running sums in plain floats (constant cost per frame)
        self._cent: deque[tuple[float, float, float]] = deque()
        self._cs = [0.0] * 6  # Στ, Στ², Σx, Σy, Στx, Στy  with τ = t − t_ref
        self._t_ref = 0.0
        self._force: deque[tuple[float, float]] = deque()
        self._fs = [0.0, 0.0]  # Σf, Σf²
        self._broad_since: float | None = None

    def _add_cent(self, t: float, x: float, y: float, sign: float) -> None:
        tau = t - self._t_ref
        c = self._cs
        c[0] += sign * tau
        c[1] += sign * tau * tau
        c[2] += sign * x
        c[3] += sign * y
        c[4] += sign * tau * x
        c[5] += sign * tau * y

    def update(self, frame: SensorFrame) -> ContactFeatures:
        """Add one frame and return the features of the contact it shows."""
        t = frame.t
        p = frame.pressure_pa.ravel()
        ea = self.array.element_area_m2
        was = self._engaged
        now = np.where(was, p > self.off_pa, p > self.on_pa)
        changed = now != was
        if changed.any():
            started = changed & now
            ended = changed & was
            self._onset[started] = t
            for d in (t - self._onset[ended]).tolist():
                self._pulses.append((t, d))
        self._engaged = now
        while self._pulses and self._pulses[0][0] < t - self.pulse_memory:
            self._pulses.popleft()

        pe = p[now]
        engaged = int(pe.size)
        # total force: every element above the noise floor (edge elements carry force too)
        total_force = float(p[p > self.floor_pa].sum()) * ea if engaged else 0.0
        in_contact = engaged > 0 and total_force >= self.min_force
        if in_contact:
            w = float(pe.sum())
            cx = float(pe @ self._xr[now]) / w
            cy = float(pe @ self._yr[now]) / w
            centroid = np.array([cx, cy])
            if not self._cent:
                self._t_ref = t
            self._cent.append((t, cx, cy))
            self._add_cent(t, cx, cy, 1.0)
            self._force.append((t, total_force))
            self._fs[0] += total_force
            self._fs[1] += total_force * total_force
        else:
            centroid = np.array([np.nan, np.nan])
            self._cent.clear()
            self._cs = [0.0] * 6
            self._force.clear()
            self._fs = [0.0, 0.0]
        while self._cent and self._cent[0][0] < t - self.vw:
            self._add_cent(*self._cent.popleft(), -1.0)
        while self._force and self._force[0][0] < t - self.sw:
            f0 = self._force.popleft()[1]
            self._fs[0] -= f0
            self._fs[1] -= f0 * f0

        vx = vy = 0.0
        n = len(self._cent)
        if n >= 3:
            st, stt, sx, sy, stx, sty = self._cs
            den = stt - st * st / n
            if den > 1e-12:
                vx, vy = (stx - st * sx / n) / den, (sty - st * sy / n) / den
        fcv = 0.0
        nf = len(self._force)
        if nf >= 2:
            mean = self._fs[0] / nf
            var = max(self._fs[1] / nf - mean * mean, 0.0)
            fcv = math.sqrt(var) / max(mean, 1e-9)

        area = engaged * ea
        if in_contact and area >= self.broad_area:
            if self._broad_since is None:
                self._broad_since = t
            broad_for = t - self._broad_since
        else:
            self._broad_since = None
            broad_for = 0.0

        ongoing = t - self._onset[now]
        if self._pulses:
            ongoing = np.concatenate([ongoing, np.fromiter((d for _, d in self._pulses), float, len(self._pulses))])
        k = ongoing.size // 2
        pulse = float(np.partition(ongoing, k)[k]) if ongoing.size else 0.0  # (upper) median
        return ContactFeatures(
            t=t, in_contact=in_contact, total_force_n=total_force, area_m2=area, engaged=engaged,
            centroid_m=centroid, peak_pa=float(p.max()), centroid_velocity_m_s=np.array([vx, vy]),
            pulse_s=pulse, force_cv=fcv, broad_for_s=broad_for,
        )
