"""Disparity of the fingertip from the finger's two side edges (the pipeline's default refinement).

One circle fit per view puts the cap centre's column off by 0.2–0.3 px on a binary skin mask: its
edge crossings lie on a half-pixel grid, and the few of them on the cap carry one set of rounding
errors. Behind the cap the distal phalanx is a cylinder: its two side edges are two parallel lines
whose mid-line is the image of the finger's axis (for a cylinder the silhouette's two tangent planes
lie symmetrically about the plane through the camera and the axis). Fitted to the mask's edge
crossings over the cylinder, twice the points of the cap fit, they place the axis to a few
hundredths of a pixel on a tilted finger, where the crossings' rounding errors change from point to
point. One rectified row is one epipolar plane, so the two views' axis columns on one row are the
same 3-D point of the axis and their difference is its disparity, with no row to match.

The axis line is best known at the mean row of its edge points, about 0.6–0.9 cap radii behind the
cap centre; extrapolated to the cap centre's row the error of its slope (a few hundredths) takes
the gain back. So the refinement takes the axis's disparity on the mean row — a point behind the
cap, nearer or further by the finger's slant in depth — and averages it with the cap fits'
disparity, whose errors are unrelated to it (``RefineConfig.axis_weight``).

Limits: the finger must not lie along the rows (``max_tilt_deg``: the disparity of a line along the
rows is undefined), both sides must be free of other skin (a side touching the palm or another
finger is dropped and the pair falls back to the cap fits), and the finger must continue behind
the cap for most of a radius.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap.vision.fingertip import _edge_points
from vishap.vision.rig import StereoRig

__all__ = ["AxisLine", "axis_line", "axis_disparity"]


@dataclass
class AxisLine:
    """The image of the finger's axis behind the cap in one rectified view: ``u = u_c + slope·(v − v_c)``
    (``centre``: the axis's point beside the cap centre)."""

    centre: np.ndarray        # (2,) the axis's point nearest the cap centre (rectified pixels)
    slope: float              # axis column per row
    points: tuple[int, int]   # edge crossings used on the left and on the right side of the axis
    rms_px: float             # residual of the crossings about the two fitted edge lines
    v_mean: float             # mean row of the crossings used (where the line's column is best known)

    def u_at(self, v: float) -> float:
        return float(self.centre[0] + self.slope * (v - self.centre[1]))


def axis_line(rig: StereoRig, side: str, mask: np.ndarray, origin, tip, *, from_radii: float, to_radii: float,
              max_tilt_deg: float, width_tol: float, max_residual_px: float, min_points: int) -> AxisLine | str:
    """The axis's image behind the cap of one view (``tip``: a Fingertip in raw pixels with ``uv``,
    ``cap_radius_px`` and ``direction``) from the skin ``mask`` whose pixel (0, 0) is raw pixel
    ``origin``; or a reason why there is none.

    The mask's edge crossings (midpoints between a skin and a non-skin neighbour, along rows and
    columns) around the finger behind the cap are taken to the rectified image. A crossing counts
    as a point of a side edge of the cylinder when it lies between ``from_radii`` and ``to_radii``
    radii behind the centre along the axis (before: the cap's own outline; after: the first joint,
    where the middle phalanx widens the finger) and within ``width_tol`` of a radius from the axis
    (a side where other skin touches the finger is further). Two parallel lines with one direction
    are fitted to the two sides' points (total least squares), points further than
    ``max_residual_px`` from their line are dropped, and the fit repeats; the axis is the mid-line.
    The detector's direction only seeds the axis, which the fit then measures. Both sides must
    reach 0.7 ``to_radii`` behind the centre (the outline of a cap with no finger behind it stops
    within a radius)."""
    r = float(tip.cap_radius_px if tip.cap_radius_px > 0 else tip.radius_px)
    uv = np.asarray(tip.uv, dtype=np.float64)
    d0 = np.asarray(tip.direction, dtype=np.float64)
    # the crossings of the mask around the finger's first to_radii + 1 radii behind the centre
    cx, cy = uv[0] - origin[0], uv[1] - origin[1]
    ex, ey = cx + (to_radii + 1.0) * r * d0[0], cy + (to_radii + 1.0) * r * d0[1]
    m = r * (1.0 + width_tol) + 2.0
    h, w = mask.shape
    x0, y0 = max(int(min(cx, ex) - m), 0), max(int(min(cy, ey) - m), 0)
    x1, y1 = min(int(max(cx, ex) + m) + 2, w), min(int(max(cy, ey) + m) + 2, h)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return f"the finger behind the cap is outside the {side} view's mask"
    e = _edge_points(mask[y0:y1, x0:x1])
    # crossings at the crop's border are the crop's, not the finger's; then a first, loose selection
    # about the detector's axis (its direction is coarse)
    rel = e - (cx - x0, cy - y0)
    along = rel @ d0
    off = np.abs(rel[:, 0] * d0[1] - rel[:, 1] * d0[0])
    sel = (e[:, 0] > 0) & (e[:, 0] < x1 - x0 - 1) & (e[:, 1] > 0) & (e[:, 1] < y1 - y0 - 1) \
        & (along >= -0.5 * r) & (along <= (to_radii + 0.5) * r) & (off >= 0.4 * r) & (off <= 1.6 * r)
    if np.count_nonzero(sel) < 2 * min_points:
        return f"{np.count_nonzero(sel)} edge points behind the cap in the {side} view"
    e = e[sel] + (x0 + origin[0], y0 + origin[1])
    pts = rig.rectify_points(np.vstack([uv, uv + 2.0 * r * d0, e]), side)
    c, p = pts[0], pts[2:]
    d = pts[1] - c
    d /= np.hypot(d[0], d[1]) + 1e-12
    keep = True
    lo, hi, tol = from_radii * r, to_radii * r, width_tol * r
    for _ in range(2):
        rel = p - c
        along = rel @ d
        off = rel[:, 0] * d[1] - rel[:, 1] * d[0]            # signed distance from the axis
        right = off > 0
        use = keep & (along >= lo) & (along <= hi) & (np.abs(np.abs(off) - r) <= tol)
        ul, ur = use & ~right, use & right
        nl, nr = int(np.count_nonzero(ul)), int(np.count_nonzero(ur))
        if min(nl, nr) < min_points:
            return f"{nl} and {nr} edge points on the finger's two sides in the {side} view (need {min_points} each)"
        reach = min(along[ul].max(), along[ur].max())
        if reach < 0.7 * hi:  # a cap's own outline stays within a radius of its centre
            return f"the finger's sides end {reach / r:.2f} radii behind the cap in the {side} view"
        ml, mr = p[ul].sum(axis=0) / nl, p[ur].sum(axis=0) / nr
        q = p - np.where(right[:, None], mr, ml)              # each side about its own mean
        S = q[use].T @ q[use]
        ang = 0.5 * np.arctan2(2.0 * S[0, 1], S[0, 0] - S[1, 1])  # the lines' common direction (total least squares)
        dn = np.array([np.cos(ang), np.sin(ang)])
        d = dn if dn @ d > 0 else -dn
        mid = 0.5 * (ml + mr)
        c = mid - ((mid - c) @ d) * d                         # the mid-line's point beside the cap centre
        res = q[:, 0] * d[1] - q[:, 1] * d[0]                 # distance from the own side's line
        keep = np.abs(res) <= max_residual_px
    if abs(d[1]) < np.cos(np.deg2rad(max_tilt_deg)):
        return f"the finger lies within {90 - max_tilt_deg:.0f}° of the rows in the {side} view"
    rms = float(np.sqrt(np.mean(np.square(res[use]))))
    return AxisLine(c, float(d[0] / d[1]), (nl, nr), rms, float(p[use, 1].mean()))


def axis_disparity(line_l: AxisLine, line_r: AxisLine, v_ref: float) -> float:
    """Disparity of the axis's point on the rectified row ``v_ref`` (one epipolar plane)."""
    return line_l.u_at(v_ref) - line_r.u_at(v_ref)
