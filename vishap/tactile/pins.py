"""HAPTEX tactile renderer: textile tile → A40/A320 → 24 contactor pins (HAPTEX §II-C, §II-E, §III-B).

Pipeline, called every 25 ms (40 Hz) on contact data that arrive at 1 kHz:

1. the 1 kHz contact stream (position, velocity, normal force) passes a causal 20 Hz Butterworth
   anti-aliasing filter before it is resampled at 40 Hz (§III-B);
2. the small-scale description — one tile of the weave as a pseudo-topology on a 0.1 mm grid — is
   read along the movement direction (periodically, several parallel lines) and Fourier-transformed
   into a spatial-frequency amplitude spectrum a(ν) (§II-C);
3. the finger speed v turns spatial into temporal frequencies, f = ν·v;
4. two band-pass weightings (Gaussian in log-frequency, centred on 40 Hz and 320 Hz) reduce the
   spectrum to the amplitudes A40 and A320 (root-sum-square of the weighted lines);
5. each of the 24 pins (6 × 4, 2 mm pitch) gets A40 and A320 weighted by the large-scale
   non-uniformity map (pseudo-amplitude on a 1 mm grid over the 200 × 200 mm sample) at the
   pin's point on the textile, multiplied by k_F·F (§III-B), and only pins inside the contact area
   are driven.

A grating of spatial period p stroked at speed v therefore puts its energy in the channel whose
centre frequency is nearest (in octaves) to v/p.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage, signal

from vishap.tactile.config import PinConfig

__all__ = ["grating_tile", "weave_tile", "nonuniformity_map", "AntiAliasFilter", "PinRenderer"]


def grating_tile(period_m: float, grid_m: float = 1e-4, amplitude_m: float = 2e-5) -> np.ndarray:
    """A sinusoidal grating along x (one period, constant along y) as a pseudo-topology tile."""
    n = max(int(round(period_m / grid_m)), 2)
    x = np.arange(n) * grid_m
    row = amplitude_m * np.cos(2 * np.pi * x / (n * grid_m))
    return np.tile(row, (n, 1))


def weave_tile(period_m: float, grid_m: float = 1e-4, amplitude_m: float = 2e-5, roughness_rms_m: float = 0.0,
               rng: np.random.Generator | None = None) -> np.ndarray:
    """One period of a plain weave: warp and weft threads crossing over/under, plus fibre roughness."""
    n = max(int(round(period_m / grid_m)), 4)
    u = (np.arange(n) + 0.5) / n
    y, x = np.meshgrid(u, u, indexing="ij")
    warp = np.abs(np.cos(2 * np.pi * y)) * (0.5 + 0.5 * np.cos(2 * np.pi * x))  # threads along x
    weft = np.abs(np.cos(2 * np.pi * x)) * (0.5 - 0.5 * np.cos(2 * np.pi * y))  # threads along y
    h = amplitude_m * (np.maximum(warp, weft) - 0.5)
    if roughness_rms_m > 0 and rng is not None:
        h = h + rng.normal(0.0, roughness_rms_m, h.shape)
    return h


def nonuniformity_map(cfg: PinConfig, rng: np.random.Generator, *, contrast: float = 0.2,
                      correlation_m: float = 0.005) -> np.ndarray:
    """Large-scale pseudo-amplitude (mean 1) on the ``map_grid_m`` grid over ``map_size_m``²."""
    n = int(round(cfg.map_size_m / cfg.map_grid_m))
    field = ndimage.gaussian_filter(rng.normal(size=(n, n)), correlation_m / cfg.map_grid_m, mode="wrap")
    field = (field - field.mean()) / max(field.std(), 1e-12)
    return np.clip(1.0 + contrast * field, 0.1, 2.0)


class AntiAliasFilter:
    """Causal Butterworth low-pass applied sample by sample to a vector of channels."""

    def __init__(self, cutoff_hz: float, rate_hz: float, n_channels: int, order: int = 2):
        self.sos = signal.butter(order, cutoff_hz, fs=rate_hz, output="sos")
        self.n = n_channels
        self.zi = None

    def reset(self, x0=None) -> None:
        self.zi = None if x0 is None else signal.sosfilt_zi(self.sos)[:, :, None] * np.asarray(x0, float)[None, None, :]

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if self.zi is None:  # start at steady state on the first sample (no start-up transient)
            self.reset(x)
        y = x
        for s in range(self.sos.shape[0]):
            b0, b1, b2, _, a1, a2 = self.sos[s]
            z = self.zi[s]
            out = b0 * y + z[0]
            z[0] = b1 * y - a1 * out + z[1]
            z[1] = b2 * y - a2 * out
            y = out
        return y


class PinRenderer:
    """The 24-pin renderer of HAPTEX §II-C with the force and contact-area integration of §III-B."""

    def __init__(self, cfg: PinConfig, tile: np.ndarray, *, umap: np.ndarray | None = None,
                 n_lines: int = 8, line_samples: int = 256):
        self.cfg = cfg
        self.tile = np.asarray(tile, dtype=np.float64)
        self.umap = umap
        self.n_lines = n_lines
        self.line_samples = line_samples
        i = np.arange(cfg.cols) - (cfg.cols - 1) / 2
        j = np.arange(cfg.rows) - (cfg.rows - 1) / 2
        jj, ii = np.meshgrid(j, i, indexing="ij")
        self.pin_pad_m = np.column_stack([cfg.centre_pad_x_m + cfg.pitch_m * ii.ravel(), cfg.pitch_m * jj.ravel()])
        self.filter = AntiAliasFilter(cfg.antialias_hz, cfg.contact_rate_hz, 5)
        self.period_s = 1.0 / cfg.update_hz
        self._spectra: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.reset()

    @property
    def n_pins(self) -> int:
        return self.pin_pad_m.shape[0]

    def reset(self) -> None:
        self.filter.reset()
        self.filtered = np.zeros(5)
        self.next_update_t = -math.inf

    # --- spectrum ------------------------------------------------------------------------------
    def spatial_spectrum(self, direction_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """(ν cycles/m, amplitude m) of the tile read along ``direction_rad`` (cached per 1°)."""
        key = int(round(math.degrees(direction_rad))) % 360
        if key not in self._spectra:
            g = self.cfg.tile_grid_m
            d = np.array([math.cos(math.radians(key)), math.sin(math.radians(key))])
            perp = np.array([-d[1], d[0]])
            n = self.line_samples
            s = np.arange(n)
            amps = []
            win = np.hanning(n)
            for k in range(self.n_lines):
                off = (k / self.n_lines) * self.tile.shape[0]
                xs = s * d[0] + off * perp[0]
                ys = s * d[1] + off * perp[1]
                line = ndimage.map_coordinates(self.tile, [ys, xs], order=1, mode="grid-wrap")
                line = (line - line.mean()) * win
                # energy-preserving scaling: a sinusoid of amplitude A gives Σ a_k² = A²
                amps.append(np.abs(np.fft.rfft(line)) * 2.0 / math.sqrt(n * np.sum(win**2)))
            a = np.sqrt(np.mean(np.square(amps), axis=0))
            nu = np.fft.rfftfreq(n, d=g)
            self._spectra[key] = (nu[1:], a[1:])
        return self._spectra[key]

    def band_weights(self, f_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Band-pass weightings of the 40 Hz and 320 Hz channels at temporal frequencies ``f_hz``."""
        sig = self.cfg.filter_octaves
        lf = np.log2(np.maximum(f_hz, 1e-6))
        w_lo = np.exp(-0.5 * ((lf - math.log2(self.cfg.f_low_hz)) / sig) ** 2)
        w_hi = np.exp(-0.5 * ((lf - math.log2(self.cfg.f_high_hz)) / sig) ** 2)
        return w_lo, w_hi

    def channel_amplitudes(self, direction_rad: float, speed_m_s: float) -> tuple[float, float]:
        """(A40, A320), normalised by ``amplitude_ref_m``, for a stroke at ``speed_m_s``."""
        if speed_m_s <= 1e-6:
            return 0.0, 0.0
        nu, a = self.spatial_spectrum(direction_rad)
        w_lo, w_hi = self.band_weights(nu * speed_m_s)
        ref = self.cfg.amplitude_ref_m
        return float(np.sqrt(np.sum((w_lo * a) ** 2)) / ref), float(np.sqrt(np.sum((w_hi * a) ** 2)) / ref)

    # --- contact stream and 40 Hz update --------------------------------------------------------
    def push_contact(self, position_xy, velocity_xy, force_n: float) -> np.ndarray:
        """Feed one 1 kHz contact sample through the anti-aliasing filter; returns the filtered vector."""
        x = np.array([position_xy[0], position_xy[1], velocity_xy[0], velocity_xy[1], force_n])
        self.filtered = self.filter(x)
        return self.filtered

    def due(self, t: float) -> bool:
        return t >= self.next_update_t - 1e-9

    def inside(self, pad_centre_m, pad_radius_m) -> np.ndarray:
        """Mask of pins inside the elliptical contact patch on the pad."""
        ax, ay = (float(pad_radius_m), float(pad_radius_m)) if np.ndim(pad_radius_m) == 0 else (float(pad_radius_m[0]), float(pad_radius_m[1]))
        if ax <= 0 or ay <= 0:
            return np.zeros(self.n_pins, dtype=bool)
        d = self.pin_pad_m - np.asarray(pad_centre_m, dtype=np.float64)
        return (d[:, 0] / ax) ** 2 + (d[:, 1] / ay) ** 2 <= 1.0

    def nonuniformity(self, points_xy: np.ndarray) -> np.ndarray:
        """Map value at surface points (object frame, metres; the sample is centred on the origin)."""
        if self.umap is None:
            return np.ones(len(points_xy))
        g = self.cfg.map_grid_m
        n = self.umap.shape[0]
        ij = points_xy / g + n / 2.0 - 0.5
        return ndimage.map_coordinates(self.umap, [ij[:, 1], ij[:, 0]], order=1, mode="nearest")

    def update(self, t: float, pad_centre_m, pad_radius_m, *, heading_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Per-pin (a40, a320), each (24,), in [0, 1] from the filtered contact data."""
        self.next_update_t = t + self.period_s
        x, y, vx, vy, force = self.filtered
        force = max(force, 0.0)
        speed = math.hypot(vx, vy)
        direction = math.atan2(vy, vx) - heading_rad
        a40, a320 = self.channel_amplitudes(direction, speed)
        inside = self.inside(pad_centre_m, pad_radius_m)
        if not inside.any() or force <= 0.0:
            z = np.zeros(self.n_pins)
            return z, z.copy()
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        rel = self.pin_pad_m - np.asarray(pad_centre_m, dtype=np.float64)
        pts = np.array([x, y]) + rel @ np.array([[c, s], [-s, c]])
        w = self.nonuniformity(pts) * inside * (self.cfg.k_force_per_n * force)
        return np.clip(w * a40, 0.0, 1.0), np.clip(w * a320, 0.0, 1.0)
