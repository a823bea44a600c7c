"""The learned background behind the device, and the fill of the deleted region (VisHap §2.1, §2.2).

VisHap learns the background "by averaging the first several images" without the hand. The same
idea, per pixel: :class:`LearnedBackground` averages every frame's pixels that show neither the hand
nor the device (the first ``average_frames`` observations of a pixel with equal weights, then an
exponential average with ``rate``, so it follows slow light changes), and remembers which pixels it
has ever seen. A pixel seen for the first time takes that frame's value.

:meth:`LearnedBackground.fill` replaces a region of a frame: from the background where it was seen,
and by ``cv2.inpaint`` (Telea or Navier–Stokes) of the background where it never was (behind a
part that never moved). That inpainting depends only on the background, so it is cached and
redone only after the never-seen area has shrunk by ``refill_fraction`` of itself (a pixel seen
since takes the background's value at once; the cached fill only serves the pixels still unseen).

:func:`inpaint_region` is the plain alternative a user would pick: inpaint the region of each frame.
"""
from __future__ import annotations

import cv2
import numpy as np

from vishap._core.errors import ConfigError, ShapeError

__all__ = ["INPAINT_METHODS", "LearnedBackground", "inpaint_region"]

INPAINT_METHODS = {"telea": cv2.INPAINT_TELEA, "ns": cv2.INPAINT_NS}


def _method(name: str) -> int:
    if name not in INPAINT_METHODS:
        raise ConfigError(f"unknown inpainting method {name!r}; expected one of {sorted(INPAINT_METHODS)}",
                          field="inpaint")
    return INPAINT_METHODS[name]


def inpaint_region(image: np.ndarray, region: np.ndarray, *, method: str = "telea", radius_px: int = 3) -> np.ndarray:
    """``cv2.inpaint`` of ``region`` (0/255) in ``image``, computed on the region's bounding box
    (plus the inpainting radius) only."""
    out = image.copy()
    x, y, w, h = cv2.boundingRect(region)
    if w == 0:
        return out
    m = radius_px + 1
    x0, y0 = max(0, x - m), max(0, y - m)
    x1, y1 = min(image.shape[1], x + w + m), min(image.shape[0], y + h + m)
    out[y0:y1, x0:x1] = cv2.inpaint(image[y0:y1, x0:x1], region[y0:y1, x0:x1], radius_px, _method(method))
    return out


class LearnedBackground:
    """Per-pixel background of one camera (BGR ``uint8`` images of ``size`` = (W, H))."""

    def __init__(self, size, *, average_frames: int = 10, rate: float = 0.05, inpaint: str = "telea",
                 inpaint_radius_px: int = 3, refill_fraction: float = 0.25, inpaint_half: bool = False):
        if not 0.0 < rate <= 1.0:
            raise ConfigError(f"rate must be in (0, 1], got {rate}", field="rate")
        self.size = (int(size[0]), int(size[1]))
        w, h = self.size
        self.average_frames = int(min(255, max(1, average_frames)))
        self.rate = float(rate)
        self.method = inpaint
        _method(inpaint)
        self.inpaint_radius_px = int(inpaint_radius_px)
        self.refill_fraction = float(refill_fraction)
        self.inpaint_half = bool(inpaint_half)
        self.mean = np.zeros((h, w, 3), np.float32)
        self.count = np.zeros((h, w), np.uint8)       # observations per pixel (stops at average_frames)
        self._filled: np.ndarray | None = None
        self._filled_unseen = 0

    @property
    def seen(self) -> np.ndarray:
        """Boolean (H, W): the pixel has been seen free of hand and device at least once."""
        return self.count > 0

    @property
    def learned(self) -> bool:
        return bool(self.count.any())

    def update(self, image: np.ndarray, free: np.ndarray, *, rate: float | None = None) -> None:
        """Take the pixels of ``image`` where ``free`` (bool or 0/255) into the background; ``rate``
        overrides the exponential average's weight for this frame."""
        if image.shape != self.mean.shape or image.dtype != np.uint8:
            raise ShapeError(f"image: expected uint8 {self.mean.shape}, got {image.dtype} {image.shape}")
        free8 = (np.asarray(free) != 0).view(np.uint8)  # 0/1
        young8 = cv2.bitwise_and(free8, cv2.compare(self.count, self.average_frames, cv2.CMP_LT))
        x, y, w, h = cv2.boundingRect(young8)
        if w:  # equal-weight average of a pixel's first observations (few pixels: work in their box)
            young = young8[y:y + h, x:x + w].view(bool)
            mean, count = self.mean[y:y + h, x:x + w], self.count[y:y + h, x:x + w]
            n = count[young].astype(np.float32) + 1.0
            mean[young] += (image[y:y + h, x:x + w][young].astype(np.float32) - mean[young]) / n[:, None]
            count[young] += 1
        old8 = cv2.bitwise_and(free8, cv2.bitwise_not(young8))
        old8 = cv2.bitwise_and(old8, cv2.compare(self.count, self.average_frames, cv2.CMP_GE))
        if cv2.countNonZero(old8):  # then an exponential average (cv2: one pass over the masked pixels)
            cv2.accumulateWeighted(image, self.mean, self.rate if rate is None else float(rate), mask=old8)

    def image(self) -> np.ndarray:
        """The background as ``uint8``, never-seen pixels inpainted (the inpainting is cached)."""
        bg = cv2.convertScaleAbs(self.mean)
        unseen = (self.count == 0).view(np.uint8) * np.uint8(255)
        n_unseen = int(np.count_nonzero(unseen))
        if n_unseen == 0 or n_unseen == unseen.size:
            return bg
        if self._filled is None or self._filled_unseen - n_unseen > self.refill_fraction * self._filled_unseen:
            self._filled, self._filled_unseen = self._inpaint(bg, unseen), n_unseen
        cv2.copyTo(self._filled, unseen, bg)
        return bg

    def _inpaint(self, bg: np.ndarray, unseen: np.ndarray) -> np.ndarray:
        """Inpaint the never-seen pixels (at half resolution with ``inpaint_half``: a quarter of the
        cost, a smoother fill)."""
        h, w = unseen.shape
        if not self.inpaint_half:
            return inpaint_region(bg, unseen, method=self.method, radius_px=self.inpaint_radius_px)
        half = (w // 2, h // 2)
        small = cv2.resize(bg, half, interpolation=cv2.INTER_AREA)
        # a half-size pixel is unknown if any of its four is: no black never-seen value leaks in
        small_unseen = cv2.threshold(cv2.resize(unseen, half, interpolation=cv2.INTER_AREA), 0, 255,
                                     cv2.THRESH_BINARY)[1]
        filled = inpaint_region(small, small_unseen, method=self.method, radius_px=max(1, self.inpaint_radius_px // 2))
        return cv2.resize(filled, (w, h), interpolation=cv2.INTER_LINEAR)

    def fill(self, image: np.ndarray, region: np.ndarray) -> np.ndarray:
        """A copy of ``image`` with ``region`` (0/255) replaced by the background."""
        out = image.copy()
        cv2.copyTo(self.image(), region, out)
        return out
