"""Camera effects applied to rendered colour images, so that no accuracy is measured on clean pixels.

Each effect models one property of a real colour camera at a realistic level and can be switched off:

* ``gain`` — auto-exposure: the gain follows the scene's mean brightness towards a target with a
  first-order lag (a light change darkens the image, then the camera recovers over a few frames:
  the illumination changes VisHap §4 tested), plus a small fixed gain mismatch between the cameras;
* ``defocus`` — a slight Gaussian blur (σ in pixels at 640 px width, scaled with resolution);
* ``motion_blur`` — a line blur along the hand's image motion during the exposure, applied to the
  hand's pixels only (the scene is static);
* ``noise`` — signal-dependent sensor noise: σ² = read² + shot·I (in 8-bit digital numbers) at the
  reference exposure (``reference_exposure_s``). A shorter exposure collects fewer photons under
  the same light and the camera's gain makes up the level (by ``e`` = reference / exposure), so the
  read noise grows by ``e`` and the shot noise's variance by ``e``: σ² = (e·read)² + e·shot·I. The
  motion blur shortens with the exposure; the image's level does not change.

The labels and depth are untouched: they are the geometry at the exposure's mid-time.
Randomness comes from ``numpy.random.Generator`` seeded by (seed, frame time, camera).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["CameraEffects", "EffectsState", "motion_blur_kernel"]


@dataclass
class CameraEffects:
    """Settings; ``CameraEffects.off()`` switches everything off (exact pixels)."""

    gain: bool = True
    defocus: bool = True
    motion_blur: bool = True
    noise: bool = True
    target_mean: float = 118.0       # auto-exposure target mean of the 8-bit image
    gain_rate: float = 0.25          # fraction of the gain error corrected per frame
    gain_limits: tuple[float, float] = (0.6, 2.5)
    gain_mismatch: float = 0.03      # right/left gain ratio − 1
    defocus_sigma_px: float = 0.7    # at 640 px image width
    exposure_s: float = 0.012        # exposure time (motion blur length = image speed × exposure)
    read_noise_dn: float = 1.6       # at the reference exposure
    shot_noise_dn: float = 0.035     # variance per DN of signal, at the reference exposure
    reference_exposure_s: float = 0.012  # the exposure the noise figures are for (the default one)

    def __post_init__(self):
        for name in ("exposure_s", "reference_exposure_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be a positive number of seconds, got {v!r}", field=name)

    @property
    def noise_gain(self) -> float:
        """The gain that makes up a shorter exposure's level (reference / exposure)."""
        return self.reference_exposure_s / self.exposure_s

    @classmethod
    def off(cls) -> "CameraEffects":
        return cls(gain=False, defocus=False, motion_blur=False, noise=False)

    @property
    def any(self) -> bool:
        return self.gain or self.defocus or self.motion_blur or self.noise


@dataclass
class EffectsState:
    """What the effects remember between frames (auto-exposure gain, previous tip pixels)."""

    gain: float | None = None
    last_t: float | None = None
    last_uv: dict = field(default_factory=dict)


def motion_blur_kernel(du: float, dv: float) -> np.ndarray | None:
    """A normalised line kernel covering a motion of (du, dv) pixels; None under half a pixel."""
    length = float(np.hypot(du, dv))
    if length < 0.5:
        return None
    n = int(np.ceil(length)) | 1
    k = np.zeros((n, n), np.float32)
    c = (n - 1) / 2.0
    steps = max(2 * n, 8)
    for s in np.linspace(-0.5, 0.5, steps):
        x, y = c + s * du, c + s * dv
        x0, y0 = int(np.floor(x)), int(np.floor(y))
        fx, fy = x - x0, y - y0
        for (xi, yi, w) in ((x0, y0, (1 - fx) * (1 - fy)), (x0 + 1, y0, fx * (1 - fy)), (x0, y0 + 1, (1 - fx) * fy), (x0 + 1, y0 + 1, fx * fy)):
            if 0 <= xi < n and 0 <= yi < n:
                k[yi, xi] += w
    return k / k.sum()


def apply_effects(
    fx: CameraEffects,
    state: EffectsState,
    images: dict[str, np.ndarray],
    skin_masks: dict[str, np.ndarray],
    tip_uv: dict[str, np.ndarray | None],
    t: float,
    seed: int,
) -> dict[str, np.ndarray]:
    """Apply the enabled effects to the BGR ``uint8`` images of both cameras (keys ``left``/``right``)."""
    if not fx.any:
        return images
    out = {}
    h, w = next(iter(images.values())).shape[:2]
    scale = w / 640.0
    # auto-exposure: one gain for the pair, driven by the left image's mean of the previous gain
    if fx.gain:
        mean = float(np.mean(images["left"])) + 1e-3
        wanted = float(np.clip(fx.target_mean / mean, *fx.gain_limits))
        if state.gain is None:
            state.gain = wanted
        else:
            state.gain += fx.gain_rate * (wanted - state.gain)
    dt = None if state.last_t is None else t - state.last_t
    for side_i, side in enumerate(("left", "right")):
        img = images[side].astype(np.float32)
        if fx.motion_blur and dt is not None and dt > 0 and tip_uv.get(side) is not None and side in state.last_uv:
            duv = (tip_uv[side] - state.last_uv[side]) * (fx.exposure_s / dt)
            k = motion_blur_kernel(float(duv[0]), float(duv[1]))
            if k is not None and skin_masks[side].any():
                # only around the hand: the blend weight is zero farther than r/2 + 4 px from it and
                # the kernel reads r/2 px beyond that, so a margin of r + 6 px changes no pixel
                r = k.shape[0]
                ys, xs = np.nonzero(skin_masks[side])
                pad = r + 6
                y0, y1 = max(0, ys.min() - pad), min(h, ys.max() + pad + 1)
                x0, x1 = max(0, xs.min() - pad), min(w, xs.max() + pad + 1)
                roi = img[y0:y1, x0:x1]
                blurred = cv2.filter2D(roi, -1, k, borderType=cv2.BORDER_REFLECT)
                m = cv2.dilate(skin_masks[side][y0:y1, x0:x1].astype(np.uint8), np.ones((r, r), np.uint8))
                m = cv2.GaussianBlur(m.astype(np.float32), (0, 0), 1.0)[..., None]
                img[y0:y1, x0:x1] = roi * (1 - m) + blurred * m
        if fx.defocus:
            img = cv2.GaussianBlur(img, (0, 0), fx.defocus_sigma_px * scale)
        if fx.gain:
            img *= state.gain * (1.0 + (fx.gain_mismatch if side == "right" else 0.0))
        if fx.noise:
            rng = np.random.default_rng([seed & 0xFFFFFFFF, int(round(t * 1e6)) & 0xFFFFFFFF, side_i])
            e = fx.noise_gain
            sigma = np.sqrt((e * fx.read_noise_dn) ** 2 + e * fx.shot_noise_dn * np.clip(img, 0, 255))
            img += rng.standard_normal(img.shape, dtype=np.float32) * sigma
        out[side] = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    state.last_t = t
    state.last_uv = {k: np.asarray(v) for k, v in tip_uv.items() if v is not None}
    return out
