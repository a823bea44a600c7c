"""The hand's mask in a real photo: a hue seed refined by a colour model of this image's own hand.

A fixed skin colour model cannot hold over real scenes: pale, brightly lit skin falls under any
saturation gate that keeps brick, soil and wood out, and those backgrounds pass any gate that
keeps the pale skin (measured in ``docs/vision.md``). What holds is the hand's own colour in this
image. :func:`adaptive_hand_mask`

1. finds the hand with the paper's hue test (strict gate): the largest skin region, preferring
   one that enters the frame (:func:`vishap.vision.view.hand_region`);
2. marks, on a ``scale``-times smaller image, that region's core as sure hand, the pixels of a
   liberal hue test (low saturation gate) near it as probable hand, saturated colours far from
   skin hue (grass, sky, blue cloth) as sure background and the rest as probable background;
3. lets OpenCV's GrabCut fit colour mixtures to hand and background *of this image* and cut
   between them (a few iterations), which takes in the pale tip and leaves out the skin-hued
   background that touches the hand only where the colours differ;
4. returns the result at full size (uint8 0/255).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from vishap.vision.segment import binary_median
from vishap.vision.skin_model import SkinModel
from vishap.vision.view import hand_region

__all__ = ["AdaptiveMaskConfig", "adaptive_hand_mask", "WINDOW"]


@dataclass(frozen=True)
class AdaptiveMaskConfig:
    scale: int = 6                  # GrabCut runs on the image shrunk by this factor
    iterations: int = 2
    liberal_min_saturation: int = 12  # saturation gate of the probable-hand hue test
    liberal_sigma_factor: float = 1.2  # … and its hue interval, times the strict one's
    near_px: int = 4                # probable hand: liberal skin within this many (small) pixels of the region
    far_hue_steps: float = 25.0     # sure background: hue this far (OpenCV steps) from the skin mean …
    far_min_saturation: int = 50    # … and at least this saturated
    within_hue: bool = True         # keep only pixels of the liberal hue test (or pale and bright)
    dark_value: int = 0             # sure background: value (brightness) below this
    seed: str = "strict"            # hand region found on the "strict" or the "liberal" hue test
    entry_sides: str = "any"        # image borders the arm may come from (view.hand_region)
    core_frac: float = 0.4          # sure hand: region pixels within this fraction of its reach from the entry


#: the setting for a tracking window around the predicted tip (small: full resolution, any side)
WINDOW = AdaptiveMaskConfig(scale=1, entry_sides="any", core_frac=1.0, near_px=2)


def adaptive_hand_mask(image: np.ndarray, skin: SkinModel, config: AdaptiveMaskConfig = AdaptiveMaskConfig()
                       ) -> np.ndarray:
    """Hand mask of a BGR image (see the module docstring); all zero when no hand region is seen."""
    c = config
    h, w = image.shape[:2]
    small = cv2.resize(image, (w // c.scale, h // c.scale), interpolation=cv2.INTER_AREA)
    hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV)
    strict = binary_median(skin.mask_hsv(hsv), 3)
    liberal_model = replace(skin, min_saturation=min(skin.min_saturation, c.liberal_min_saturation),
                            max_sigma=skin.max_sigma * c.liberal_sigma_factor)
    liberal = binary_median(liberal_model.mask_hsv(hsv), 3)
    region = hand_region(liberal if c.seed == "liberal" else strict, entry_sides=c.entry_sides)
    if c.seed == "strict" and (region is None or not _enters(region, strict.shape, c.entry_sides)):
        # pale skin in bright light can fall apart under the strict gate: find the hand on the liberal test
        region = hand_region(liberal, entry_sides=c.entry_sides) or region
    if region is None:
        return np.zeros((h, w), np.uint8)
    liberal = liberal > 0
    gc = np.full(strict.shape, cv2.GC_PR_BGD, np.uint8)
    hue = hsv[..., 0].astype(np.int16)
    dh = np.abs((hue - int(round(skin.hue_mean)) + 90) % 180 - 90)
    gc[(hsv[..., 1] > c.far_min_saturation) & (dh > c.far_hue_steps)] = cv2.GC_BGD
    gc[hsv[..., 2] < c.dark_value] = cv2.GC_BGD  # black furniture, deep shadow: never the hand's skin
    k = 2 * c.near_px + 1
    near = cv2.dilate(region.label_mask, np.ones((k, k), np.uint8)) > 0
    gc[liberal & near] = cv2.GC_PR_FGD
    core = (cv2.erode(region.label_mask, np.ones((5, 5), np.uint8)) > 0) & (strict > 0)
    if c.core_frac < 1.0:
        # sure hand only near where it enters: a skin-hued surface the hand touches (soil, a
        # wall) belongs to the region but is left for the colour models to decide
        ys, xs = np.nonzero(region.label_mask)
        dist = np.hypot(xs - region.entry_uv[0], ys - region.entry_uv[1])
        yy, xx = np.mgrid[0:core.shape[0], 0:core.shape[1]]
        core &= np.hypot(xx - region.entry_uv[0], yy - region.entry_uv[1]) <= c.core_frac * dist.max()
    if not core.any():
        core = region.label_mask > 0
    gc[core] = cv2.GC_FGD
    bgd, fgd = np.zeros((1, 65)), np.zeros((1, 65))
    try:
        cv2.grabCut(small, gc, None, bgd, fgd, c.iterations, cv2.GC_INIT_WITH_MASK)
    except cv2.error:  # one class empty (e.g. the whole image is hand): keep the seed
        gc = np.where(liberal & near, cv2.GC_PR_FGD, cv2.GC_BGD).astype(np.uint8)
    fg = ((gc == cv2.GC_FGD) | (gc == cv2.GC_PR_FGD)).view(np.uint8) * 255
    if not c.within_hue:
        return cv2.threshold(cv2.resize(fg, (w, h), interpolation=cv2.INTER_LINEAR), 0, 255, cv2.THRESH_BINARY)[1]
    # the cut may follow shading into dark or grey surroundings: keep skin hues (or pale, bright
    # pixels) only, tested at full resolution so that the edges — the cap the tip is fitted to —
    # are the image's, not the small cut's
    fg = cv2.dilate(cv2.resize(fg, (w, h), interpolation=cv2.INTER_NEAREST), np.ones((c.scale + 1, c.scale + 1), np.uint8))
    x, y, bw, bh = cv2.boundingRect(fg)
    hsv_full = cv2.cvtColor(image[y:y + bh, x:x + bw], cv2.COLOR_BGR2HSV)
    keep = cv2.bitwise_or(liberal_model.mask_hsv(hsv_full),
                          cv2.inRange(hsv_full, (0, 0, 151), (180, c.liberal_min_saturation - 1, 255)))
    out = np.zeros((h, w), np.uint8)
    out[y:y + bh, x:x + bw] = cv2.bitwise_and(fg[y:y + bh, x:x + bw], binary_median(keep, 3))
    return out


def _enters(region, shape, sides: str) -> bool:
    """Does the region touch one of the image borders ``sides`` ("any": all four)?"""
    h, w = shape
    ys, xs = np.nonzero(region.label_mask)
    touch = {"left": xs.min() <= 1, "top": ys.min() <= 1, "right": xs.max() >= w - 2, "bottom": ys.max() >= h - 2}
    return any(touch.values()) if sides == "any" else any(touch[s.strip()] for s in sides.split(",") if s.strip())
