"""One camera's fingertip search: the per-view step the mono detector and the stereo pipeline share.

:func:`search_tips` runs the paper's detector (:func:`vishap.vision.fingertip.detect_fingertips`)
on one view's skin mask at one or several radii ``r = K/z`` (several when the depth is unknown),
drops candidates that repeat one found at another radius, and returns them in full-image
coordinates. :func:`hand_tip` is the finger-of-the-hand choice for real scenes (the skin region
that enters the frame, its principal axis, the finger's extreme point along it), used where
candidates ranked by distance from a centroid fail (a braid's end, a skin-coloured wall).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vishap.vision.fingertip import Fingertip, FingertipConfig, detect_fingertips

__all__ = ["search_tips", "HandRegion", "hand_region", "hand_tip"]


def search_tips(mask: np.ndarray, radii, config: FingertipConfig, *, origin=(0, 0), prior_uv=None,
                max_tips: int = 4, by_extremity: bool = True) -> list[Fingertip]:
    """Fingertip candidates of a mask (a region of the image whose top-left corner is ``origin``)
    at each radius of ``radii`` in turn; a candidate within its own radius of an earlier one is a
    repeat. With several radii the list is re-ranked by extremity (``by_extremity``) and cut to
    ``max_tips``. ``prior_uv`` is in full-image coordinates. Returned ``uv`` are full-image."""
    radii = list(radii)
    tips: list[Fingertip] = []
    for r in radii:
        for tip in detect_fingertips(mask, r, config, prior_uv=prior_uv, max_tips=max_tips, origin=origin):
            if all(np.hypot(*(tip.uv - o.uv)) > tip.radius_px for o in tips):
                tips.append(tip)
    if len(radii) > 1 and by_extremity:
        tips.sort(key=lambda tp: -tp.extremity_px)
    return tips[:max_tips]


@dataclass
class HandRegion:
    """The skin region taken as the hand, in image pixels."""

    label_mask: np.ndarray     # uint8 0/255, the region only
    entry_uv: np.ndarray       # where the hand comes from (border contact, else the region's far end)
    axis: np.ndarray           # unit principal axis, pointing from the entry into the region
    area_px: int
    touches_border: bool


def hand_region(mask: np.ndarray, *, min_area_frac: float = 0.002,
                entry_sides: str = "any") -> HandRegion | None:
    """The hand among the skin regions of a mask: the largest region, preferring one that enters the
    frame from one of ``entry_sides`` (a hand in front of a camera comes in with its arm from an
    image border — the user's side: bottom, left or right for a camera facing the user's
    workspace, a head-worn camera or a phone held in the other hand —, a wall blob or a face need
    not; "any" accepts the top too).

    The entry point is the mean of the region's border pixels; without border contact it is the end
    of the principal axis nearer an image border."""
    h, w = mask.shape
    n, lab, stats, cents = cv2.connectedComponentsWithStats((mask > 0).view(np.uint8), connectivity=8)
    if n <= 1:
        return None
    areas = stats[1:, cv2.CC_STAT_AREA]
    min_area = max(30, int(min_area_frac * h * w))
    ok = np.flatnonzero(areas >= min_area) + 1
    if ok.size == 0:
        return None
    x0, y0 = stats[ok, cv2.CC_STAT_LEFT], stats[ok, cv2.CC_STAT_TOP]
    x1, y1 = x0 + stats[ok, cv2.CC_STAT_WIDTH], y0 + stats[ok, cv2.CC_STAT_HEIGHT]
    sides = {"left": x0 <= 1, "top": y0 <= 1, "right": x1 >= w - 1, "bottom": y1 >= h - 1}
    wanted = sides if entry_sides == "any" else [sd.strip() for sd in entry_sides.split(",") if sd.strip()]
    border = np.zeros(ok.size, bool)
    for sd in wanted:
        border |= sides[sd]
    # a region touching the border counts double: a hand enters the frame
    k = ok[int(np.argmax(stats[ok, cv2.CC_STAT_AREA] * np.where(border, 2.0, 1.0)))]
    region = (lab == k)
    ys, xs = np.nonzero(region)
    pts = np.column_stack([xs, ys]).astype(np.float64)
    c = pts.mean(axis=0)
    q = pts - c
    cov = q.T @ q / len(q)
    evals, evecs = np.linalg.eigh(cov)
    axis = evecs[:, 1]
    edge = (xs <= 1) | (ys <= 1) | (xs >= w - 2) | (ys >= h - 2)
    touches = bool(edge.sum() >= 3)
    if touches:
        entry = pts[edge].mean(axis=0)
    else:
        # the arm is cut off outside the view or by the frame's edge: the end of the principal
        # axis nearer an image border
        s = q @ axis
        ends = [c + axis * s.max(), c + axis * s.min()]
        entry = min(ends, key=lambda e: min(e[0], e[1], w - 1 - e[0], h - 1 - e[1]))
    d = c - entry
    if d @ axis < 0:
        axis = -axis
    return HandRegion(region.view(np.uint8) * 255, entry, axis, int(len(pts)), touches)


def hand_tip(region: HandRegion, *, axis_weight: float = 0.5) -> np.ndarray:
    """The finger's extreme point: the region's pixel farthest from the entry point, measured along a
    blend of the direction from the entry and the principal axis (``axis_weight``: 0 = plain
    distance from the entry, 1 = the extreme along the principal axis only)."""
    m = region.label_mask
    cnts, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = np.concatenate([c.reshape(-1, 2) for c in cnts]).astype(np.float64)
    rel = pts - region.entry_uv
    dist = np.hypot(rel[:, 0], rel[:, 1])
    along = rel @ region.axis
    score = (1 - axis_weight) * dist + axis_weight * along
    return pts[int(np.argmax(score))]
