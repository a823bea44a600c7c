"""Single-Gaussian hue skin model (VisHap §2.1, "Appearance-based Hand Segmentation").

The paper learns, offline, "a single Gaussian model of the hue distribution" of skin pixels from
labelled image sequences, and keeps a foreground pixel when the probability that it belongs to the
skin model exceeds a threshold. A Gaussian density thresholded at a fixed probability is the same
as a bound on the Mahalanobis distance ``|h - mean| / std <= max_sigma``, so the test becomes a hue
interval that OpenCV's ``inRange`` evaluates in one pass.

Hue is circular (OpenCV 8-bit hue: 0…179, i.e. 2° per step; skin sits near the 0/180 wrap), so the
mean is the circular mean and deviations are wrapped into (−90, 90]. Hue is undefined for
achromatic pixels (grey, black, white): pixels with saturation below ``min_saturation`` or value
below ``min_value`` are never skin. That gate is the one addition to the paper's hue-only model.
"""
from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from vishap._core.config import Schema, load_config, write_atomic
from vishap._core.errors import ConfigError, ShapeError

__all__ = ["SkinModel", "default_skin_model_path", "hue_of"]

_HUE_RANGE = 180  # OpenCV 8-bit hue


def default_skin_model_path() -> Path:
    """The shipped model, fitted from labelled synthetic frames (see ``docs/vision.md``)."""
    return Path(__file__).with_name("data") / "skin_model.yaml"


def hue_of(image_bgr: np.ndarray) -> np.ndarray:
    """HSV (OpenCV 8-bit) of a BGR image."""
    return cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)


class _SkinSchema(Schema):
    hue_mean: float
    hue_std: float
    max_sigma: float = 2.5
    min_saturation: int = 40
    min_value: int = 30
    n_samples: int = 0
    source: str = ""


@dataclass
class SkinModel:
    """Gaussian on OpenCV hue (0…179, circular) plus an achromatic gate.

    Attributes
    ----------
    hue_mean, hue_std: the Gaussian, in OpenCV hue steps (2° each).
    max_sigma: keep pixels with ``|h - hue_mean| <= max_sigma * hue_std`` (probability threshold).
    min_saturation, min_value: 0…255; below either the hue is undefined and the pixel is not skin.
    """

    hue_mean: float = 10.0
    hue_std: float = 4.0
    max_sigma: float = 2.5
    min_saturation: int = 40
    min_value: int = 30
    n_samples: int = 0
    source: str = ""

    def __post_init__(self) -> None:
        if not (self.hue_std > 0 and math.isfinite(self.hue_std)):
            raise ConfigError(f"hue_std must be positive, got {self.hue_std}", field="hue_std")
        if not (self.max_sigma > 0):
            raise ConfigError(f"max_sigma must be positive, got {self.max_sigma}", field="max_sigma")
        self.hue_mean = float(self.hue_mean) % _HUE_RANGE
        self._ranges = self._hue_ranges()
        lut = np.zeros(256, np.uint8)
        for lo, hi in self._ranges:
            lut[lo: hi + 1] = 255
        self.hue_lut = lut  # the hue test alone (255 inside the interval), for callers that apply the gate themselves

    # ------------------------------------------------------------------ fitting
    @classmethod
    def fit(cls, images, labels, *, skin_label: int = 1, max_sigma: float | None = None, coverage: float = 0.99,
            min_saturation: int = 40, min_value: int = 30, source: str = "") -> "SkinModel":
        """Fit the Gaussian to the hue of labelled skin pixels of BGR ``images``.

        Pixels with label ``skin_label`` that pass the achromatic gate are used. The probability
        threshold (``max_sigma``) is, unless given, the one that keeps the fraction ``coverage`` of
        the training skin pixels.
        """
        sums = np.zeros(2)
        hues = []
        for img, lab in zip(images, labels):
            if img.shape[:2] != lab.shape:
                raise ShapeError(f"image {img.shape[:2]} and labels {lab.shape} differ in size")
            hsv = hue_of(img)
            sel = (lab == skin_label) & (hsv[..., 1] >= min_saturation) & (hsv[..., 2] >= min_value)
            hues.append(hsv[..., 0][sel].astype(np.float64))
        h = np.concatenate(hues) if hues else np.empty(0)
        if h.size < 10:
            raise ConfigError(f"too few labelled skin pixels to fit a skin model ({h.size})", field="labels")
        ang = h * (2 * np.pi / _HUE_RANGE)
        sums[:] = np.sin(ang).sum(), np.cos(ang).sum()
        mean = (math.atan2(sums[0], sums[1]) * _HUE_RANGE / (2 * np.pi)) % _HUE_RANGE
        d = _wrap(h - mean)
        std = float(max(np.sqrt(np.mean(d * d)), 0.5))
        if max_sigma is None:
            max_sigma = float(np.quantile(np.abs(d), coverage) / std)
        return cls(hue_mean=float(mean), hue_std=std,
                   max_sigma=max_sigma, min_saturation=min_saturation, min_value=min_value,
                   n_samples=int(h.size), source=source)

    # ------------------------------------------------------------------ evaluation
    def _hue_ranges(self) -> list[tuple[int, int]]:
        half = self.max_sigma * self.hue_std
        lo = math.ceil(self.hue_mean - half - 1e-9)
        hi = math.floor(self.hue_mean + half + 1e-9)
        if hi - lo + 1 >= _HUE_RANGE:
            return [(0, _HUE_RANGE - 1)]
        if lo < 0:
            return [(0, hi), (lo + _HUE_RANGE, _HUE_RANGE - 1)]
        if hi >= _HUE_RANGE:
            return [(lo, _HUE_RANGE - 1), (0, hi - _HUE_RANGE)]
        return [(lo, hi)]

    def mask_hsv(self, hsv: np.ndarray) -> np.ndarray:
        """Skin mask (uint8 0/255) of an HSV image (OpenCV 8-bit)."""
        out = None
        for lo, hi in self._ranges:
            m = cv2.inRange(hsv, (lo, self.min_saturation, self.min_value), (hi, 255, 255))
            out = m if out is None else cv2.bitwise_or(out, m, dst=out)
        return out

    def mask(self, image_bgr: np.ndarray) -> np.ndarray:
        """Skin mask (uint8 0/255) of a BGR image."""
        return self.mask_hsv(hue_of(image_bgr))

    def log_likelihood(self, hue) -> np.ndarray:
        """Gaussian log density of OpenCV hue values (for charts and tests)."""
        d = _wrap(np.asarray(hue, dtype=np.float64) - self.hue_mean)
        return -0.5 * (d / self.hue_std) ** 2 - math.log(self.hue_std * math.sqrt(2 * math.pi))

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> Path:
        import yaml

        d = asdict(self)
        return write_atomic(path, "# vishap skin model: Gaussian on OpenCV hue (0..179)\n" + yaml.safe_dump(d, sort_keys=False))

    @classmethod
    def load(cls, path: str | os.PathLike | None = None) -> "SkinModel":
        """Read a model file (default: the shipped one); problems raise :class:`ConfigError`."""
        path = default_skin_model_path() if path is None else Path(path)
        s = load_config(path, _SkinSchema)
        try:
            return cls(**s.model_dump())
        except ConfigError as exc:
            raise ConfigError(exc.reason, file=path, field=exc.field) from None


def _wrap(d: np.ndarray) -> np.ndarray:
    """Wrap hue differences into [-90, 90)."""
    return (d + _HUE_RANGE / 2) % _HUE_RANGE - _HUE_RANGE / 2
