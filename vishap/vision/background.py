"""A background model for real use: never learned from frames that hold the hand.

The paper learns the tile histograms from the average of the first frames. With a real camera the
hand is often in view from the first frame, and the background then *is* the hand: the skin test
passes nowhere. :class:`HandFreeBackground` wraps a :class:`~vishap.vision.segment.Segmenter` and

* learns only from frames in which the detector found no hand (``observe(..., hand_uv=None)``),
  ``learn_frames`` of them; until then the detector runs on the skin test alone and ``status``
  says why ("hand in view: background not learned from it");
* keeps updating the pixels the hand is not over (a running average, ``update_rate`` per frame,
  applied every ``refresh_every`` frames; pixels farther than ``hand_clear_px`` from the hand and
  off its skin);
* notices a moving camera — most of the image outside the hand differs from the learned
  background (a grey thumbnail, ``moving_frac`` of its pixels off by more than
  ``moving_level``) — and falls back to the skin test alone (``usable`` False, ``status``
  "camera moving: skin only") until the view is still again, then relearns.
"""
from __future__ import annotations

import cv2
import numpy as np

from vishap.vision.segment import Segmenter

__all__ = ["HandFreeBackground"]


class HandFreeBackground:
    def __init__(self, seg: Segmenter, *, learn_frames: int = 10, update_rate: float = 0.05,
                 hand_clear_px: float = 80.0, moving_frac: float = 0.35, moving_level: int = 25,
                 refresh_every: int = 10):
        self.seg = seg
        self.learn_frames = learn_frames
        self.update_rate = update_rate
        self.hand_clear_px = hand_clear_px
        self.moving_frac = moving_frac
        self.moving_level = moving_level
        self.refresh_every = refresh_every
        self._buf: list[np.ndarray] = []
        self._mean: np.ndarray | None = None     # float32 running background image
        self._thumb: np.ndarray | None = None
        self._prev_thumb: np.ndarray | None = None
        self.hand_seen_unlearned = 0             # frames with the hand in view before a background exists
        self.moving = False
        self._n = 0

    @property
    def usable(self) -> bool:
        return self.seg.learned and not self.moving

    @property
    def status(self) -> str:
        if self.moving:
            return "camera moving: skin only"
        if self.seg.learned:
            return "background"
        if self.hand_seen_unlearned:
            return "hand in view: background not learned from it (skin only)"
        return "learning the background (skin only)"

    def observe(self, image: np.ndarray, t: float, hand_uv=None) -> None:
        """Feed one frame and where the hand was found in it (None: no hand)."""
        thumb = cv2.resize(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), (80, 60), interpolation=cv2.INTER_AREA)
        self.moving = self._camera_moved(thumb, image.shape, hand_uv)
        self._prev_thumb = thumb
        if self.moving:
            self._buf = []
            return
        if not self.seg.learned:
            if hand_uv is not None:
                self.hand_seen_unlearned += 1
                self._buf = []  # only consecutive hand-free frames make a background
                return
            self._buf.append(image)
            if len(self._buf) >= self.learn_frames:
                self.seg.learn(self._buf)
                self._mean = self.seg.mean_image.astype(np.float32)
                self._thumb = cv2.resize(cv2.cvtColor(self.seg.mean_image, cv2.COLOR_BGR2GRAY), (80, 60),
                                         interpolation=cv2.INTER_AREA)
                self._buf = []
            return
        self._update(image, hand_uv)

    def _camera_moved(self, thumb: np.ndarray, shape, hand_uv) -> bool:
        ref = self._thumb if self.seg.learned else self._prev_thumb
        if ref is None:
            return False
        diff = cv2.absdiff(thumb, ref) > self.moving_level
        if hand_uv is not None:  # the hand's neighbourhood may differ: leave it out
            sx, sy = 80 / shape[1], 60 / shape[0]
            cv2.circle(diff.view(np.uint8), (int(hand_uv[0] * sx), int(hand_uv[1] * sy)),
                       int(2 * self.hand_clear_px * sx), 0, -1)
        moved = float(diff.mean()) > self.moving_frac
        if moved and self.seg.learned and self._prev_thumb is not None:
            # a still camera after the move: the new view becomes the background again
            if float((cv2.absdiff(thumb, self._prev_thumb) > self.moving_level).mean()) < 0.05:
                self.seg.background = None
                self._thumb = None
                return False
        return moved

    def _update(self, image: np.ndarray, hand_uv) -> None:
        self._n += 1
        if self._n % self.refresh_every:
            return  # one blend every refresh_every frames, at refresh_every times the rate: a full-frame
            #         float blend per frame would cost more than the tracked search itself
        rate = min(1.0, self.update_rate * self.refresh_every)
        mask = np.full(image.shape[:2], rate, np.float32)
        if hand_uv is not None:
            cv2.circle(mask, (int(hand_uv[0]), int(hand_uv[1])), int(self.hand_clear_px), 0.0, -1)
        # the hand's body lies beyond its tip too: clear also the skin pixels of the frame
        skin = self.seg.skin.mask_hsv(cv2.cvtColor(image, cv2.COLOR_BGR2HSV))
        mask[cv2.dilate(skin, np.ones((15, 15), np.uint8)) > 0] = 0.0
        m3 = mask[..., None]
        self._mean += m3 * (image.astype(np.float32) - self._mean)
        mean = cv2.convertScaleAbs(self._mean)
        self.seg.mean_image = mean
        self.seg.background = self.seg.histograms(mean)
        self._thumb = cv2.resize(cv2.cvtColor(mean, cv2.COLOR_BGR2GRAY), (80, 60), interpolation=cv2.INTER_AREA)
