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

import math
from dataclasses import dataclass

import numpy as np

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
    cap: np.ndarray           # (2,) the detector's cap centre in the rectified view

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
    u, v = float(tip.uv[0]), float(tip.uv[1])
    d0x, d0y = float(tip.direction[0]), float(tip.direction[1])
    # the crossings of the mask around the finger's first to_radii + 1 radii behind the centre
    cx, cy = u - origin[0], v - origin[1]
    ex, ey = cx + (to_radii + 1.0) * r * d0x, cy + (to_radii + 1.0) * r * d0y
    m = r * (1.0 + width_tol) + 2.0
    mh, mw = mask.shape
    x0, y0 = max(int(min(cx, ex) - m), 0), max(int(min(cy, ey) - m), 0)
    x1, y1 = min(int(max(cx, ex) + m) + 2, mw), min(int(max(cy, ey) + m) + 2, mh)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return f"the finger behind the cap is outside the {side} view's mask"
    # points as complex numbers u + iv: (z − c)·conj(d) is (along the axis) − i(signed distance from it)
    z = _inner_crossings(mask[y0:y1, x0:x1])
    # a first, loose selection about the detector's axis (its direction is coarse)
    w = (z - complex(cx - x0, cy - y0)) * complex(d0x, -d0y)
    off = np.abs(w.imag)
    sel = (w.real >= -0.5 * r) & (w.real <= (to_radii + 0.5) * r) & (off >= 0.4 * r) & (off <= 1.6 * r)
    n = int(np.count_nonzero(sel))
    if n < 2 * min_points:
        return f"{n} edge points behind the cap in the {side} view"
    # the cap centre, a point on the detector's axis and the crossings, rectified in one call
    raw = np.empty(n + 2, complex)
    raw[0] = complex(u, v)
    raw[1] = complex(u + 2.0 * r * d0x, v + 2.0 * r * d0y)
    raw[2:] = z[sel] + complex(x0 + origin[0], y0 + origin[1])
    rect = rig.rectify_points(raw.view(np.float64).reshape(-1, 2), side)
    cap = rect[0]
    p = rect[2:].view(complex).ravel()
    c = complex(*rect[0])
    d = complex(*rect[1]) - c
    d /= abs(d) + 1e-12
    keep = None
    lo, hi, tol = from_radii * r, to_radii * r, width_tol * r
    for it in range(2):
        w = (p - c) * d.conjugate()
        along, across = w.real, w.imag                        # across: minus the signed distance from the axis
        right = across < 0
        use = (along >= lo) & (along <= hi) & (np.abs(np.abs(across) - r) <= tol)
        if keep is not None:
            use &= keep
        ur = use & right
        ul = use ^ ur
        nl, nr = int(np.count_nonzero(ul)), int(np.count_nonzero(ur))
        if min(nl, nr) < min_points:
            return f"{nl} and {nr} edge points on the finger's two sides in the {side} view (need {min_points} each)"
        reach = min(float(along[ul].max()), float(along[ur].max()))
        if reach < 0.7 * hi:  # a cap's own outline stays within a radius of its centre
            return f"the finger's sides end {reach / r:.2f} radii behind the cap in the {side} view"
        ml, mr = complex(p[ul].sum()) / nl, complex(p[ur].sum()) / nr
        q = p - np.where(right, mr, ml)                       # each side about its own mean
        qu = q[use]
        s2 = complex((qu * qu).sum())                         # Σ(qx² − qy²) + 2iΣqx·qy
        ang = 0.5 * math.atan2(s2.imag, s2.real)              # the lines' common direction (total least squares)
        dn = complex(math.cos(ang), math.sin(ang))
        d = dn if (dn * d.conjugate()).real > 0 else -dn
        mid = 0.5 * (ml + mr)
        c = mid - ((mid - c) * d.conjugate()).real * d        # the mid-line's point beside the cap centre
        if it == 0:
            keep = np.abs((q * d.conjugate()).imag) <= max_residual_px  # distance from the own side's line
    if abs(d.imag) < math.cos(math.radians(max_tilt_deg)):
        return f"the finger lies within {90 - max_tilt_deg:.0f}° of the rows in the {side} view"
    res = (qu * d.conjugate()).imag
    rms = math.sqrt(float(res @ res) / (nl + nr))
    return AxisLine(np.array([c.real, c.imag]), d.real / d.imag, (nl, nr), rms, float(p[use].imag.mean()), cap)


def _inner_crossings(crop: np.ndarray) -> np.ndarray:
    """The midpoints (complex, column + i·row) between horizontally/vertically adjacent pixels of ``crop``
    of which one is skin and one not, leaving out those on the crop's border rows and columns (the
    crop's, not the finger's): the edge crossings inside the crop."""
    b = crop > 0
    hy, hx = np.nonzero(b[1:-1, 1:] != b[1:-1, :-1])
    vy, vx = np.nonzero(b[1:, 1:-1] != b[:-1, 1:-1])
    z = np.empty(len(hx) + len(vx), complex)
    z.real[:len(hx)], z.imag[:len(hx)] = hx + 0.5, hy + 1.0
    z.real[len(hx):], z.imag[len(hx):] = vx + 1.0, vy + 0.5
    return z


def axis_disparity(line_l: AxisLine, line_r: AxisLine, v_ref: float) -> float:
    """Disparity of the axis's point on the rectified row ``v_ref`` (one epipolar plane)."""
    return line_l.u_at(v_ref) - line_r.u_at(v_ref)
