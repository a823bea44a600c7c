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

The axis's disparity is precise but not unbiased: its point lies behind the cap on a finger
slanted in depth, and the outline behind the cap is not a perfect cylinder (a nail, a taper); on
the standard renders it reads 0.07–0.17 px more than the truth, 0.6–1.5 mm of depth toward the
camera, while the cap fits' disparity is unbiased but noisier. :class:`AxisLevel` is the
complementary filter of the two: the cap fits give the level (the axis's offset from them, averaged
over seconds, follows the finger's shape and slant), the axis gives the frame-to-frame detail, and
the two are weighed by their noise and the level's own uncertainty.

Limits: the finger must not lie along the rows (``max_tilt_deg``: the disparity of a line along the
rows is undefined), both sides must be free of other skin (a side touching the palm or another
finger is dropped and the pair falls back to the cap fits), and the finger must continue behind
the cap for most of a radius.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from vishap.vision.rig import StereoRig

__all__ = ["AxisLine", "AxisLevel", "axis_line", "axis_lines", "axis_disparity"]


@dataclass
class AxisLine:
    """The image of the finger's axis behind the cap in one rectified view: ``u = u_c + slope·(v − v_c)``
    (``centre``: the axis's point nearest the cap centre)."""

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
    return axis_lines(rig, [(side, mask, origin, tip)], from_radii=from_radii, to_radii=to_radii,
                      max_tilt_deg=max_tilt_deg, width_tol=width_tol, max_residual_px=max_residual_px,
                      min_points=min_points)[0]


def axis_lines(rig: StereoRig, views, *, from_radii: float, to_radii: float, max_tilt_deg: float, width_tol: float,
               max_residual_px: float, min_points: int) -> list:
    """:func:`axis_line` of several views at once (``views``: ``(side, mask, origin, tip)`` each): the
    same lines, with the fit's array work done once for all views' points (a tracked pair spends its
    time on the number of NumPy calls, not on their 50–60 points per view). Returns one entry per
    view, an :class:`AxisLine` or the reason; after the first view that fails, the rest are not fitted
    (their entries repeat that reason)."""
    seeds, parts = [], []
    for side, mask, origin, tip in views:
        got = _side_points(rig, side, mask, origin, tip, to_radii, width_tol, min_points)
        if isinstance(got, str):
            return [got] * len(views)
        seeds.append(got[:3])
        parts.append(got[3])
    K = len(views)
    counts = [len(q) for q in parts]
    p = np.concatenate(parts)                                 # each view's points about its cap centre
    uv = p.view(np.float64).reshape(-1, 2)                    # … as (u, v) rows
    # each point as (u, v, 1) in its view's block of three columns: one product maps every point
    # into its own view's axis frame
    X = np.zeros((len(p), 3 * K))
    start = 0
    for k, n in enumerate(counts):
        X[start:start + n, 3 * k: 3 * k + 2] = uv[start:start + n]
        X[start:start + n, 3 * k + 2] = 1.0
        start += n
    mom = np.empty((len(p), 6))                               # 1, u, v, u², v², uv
    mom[:, 0] = 1.0
    mom[:, 1:3] = uv
    np.multiply(uv, uv, out=mom[:, 3:5])
    np.multiply(uv[:, 0], uv[:, 1], out=mom[:, 5])
    even, ids = (_EVEN[:K], _IDS[:2 * K]) if K <= len(_EVEN) else (2 * np.arange(K), np.arange(2 * K)[:, None])
    group_base = even.repeat(counts)  # the left side of view k is group 2k
    c = [0j] * K                                               # the axis's point beside the cap (about the cap)
    d = [s[1] for s in seeds]                                  # unit direction into the finger
    keep = None
    for it in range(2):
        # (along the axis, minus the signed distance from it), in cap radii: (p − c)·conj(d) / r
        A = []
        for k in range(K):
            f = d[k].conjugate() / seeds[k][0]
            g = c[k] * f
            A += [(f.real, f.imag), (-f.imag, f.real), (-g.real, -g.imag)]
        w = X @ np.array(A)
        along, across = w[:, 0], w[:, 1]
        right = across < 0
        use = (along >= from_radii) & (along <= to_radii) & (np.abs(np.abs(across) - 1.0) <= width_tol)
        if keep is not None:
            use &= keep
        group = group_base + right                             # left side of view k: 2k, right side: 2k + 1
        sel = (group == ids) & use                             # (2K, N)
        S = (sel @ mom).tolist()
        reach = np.maximum.reduce(sel * along, axis=1).tolist()
        means = []
        for k in range(K):
            sl, sr = S[2 * k], S[2 * k + 1]
            nl, nr = int(sl[0]), int(sr[0])
            side = views[k][0]
            if min(nl, nr) < min_points:
                return [f"{nl} and {nr} edge points on the finger's two sides in the {side} view "
                        f"(need {min_points} each)"] * K
            rc = min(reach[2 * k], reach[2 * k + 1])
            if rc < 0.7 * to_radii:  # a cap's own outline stays within a radius of its centre
                return [f"the finger's sides end {rc:.2f} radii behind the cap in the {side} view"] * K
            ml, mr = complex(sl[1], sl[2]) / nl, complex(sr[1], sr[2]) / nr
            # the two sides' second moments about their own means, pooled: Σ(qx² − qy²) + 2iΣqx·qy
            cuu = sl[3] - sl[1] * ml.real + sr[3] - sr[1] * mr.real
            cvv = sl[4] - sl[2] * ml.imag + sr[4] - sr[2] * mr.imag
            cuv = sl[5] - sl[1] * ml.imag + sr[5] - sr[1] * mr.imag
            ang = 0.5 * math.atan2(2.0 * cuv, cuu - cvv)          # the lines' common direction (total least squares)
            dn = complex(math.cos(ang), math.sin(ang))
            dk = dn if (dn * d[k].conjugate()).real > 0 else -dn
            mid = 0.5 * (ml + mr)
            c[k] = mid - ((mid - c[k]) * dk.conjugate()).real * dk  # the mid-line's point beside the cap centre
            d[k] = dk
            means.append((ml, mr, nl, nr, cuu, cvv, cuv, sl[2] + sr[2]))
        if it == 0:  # distance from the own side's line (the sides as split before the refit): (p − m)·conj(d) imag
            B, off = [], []
            for k in range(K):
                dk = d[k]
                B += [-dk.imag, dk.real, 0.0]
                off += [(means[k][0] * dk.conjugate()).imag, (means[k][1] * dk.conjugate()).imag]
            keep = np.abs(X @ np.array(B) - np.array(off)[group]) <= max_residual_px
    out = []
    cos_tilt = math.cos(math.radians(max_tilt_deg))
    for k in range(K):
        dk, (ml, mr, nl, nr, cuu, cvv, cuv, sv) = d[k], means[k]
        if abs(dk.imag) < cos_tilt:
            return [f"the finger lies within {90 - max_tilt_deg:.0f}° of the rows in the {views[k][0]} view"] * K
        # Σ((q·conj d).imag)² of the pooled, centred points, from their second moments
        res2 = dk.real * dk.real * cvv - 2.0 * dk.real * dk.imag * cuv + dk.imag * dk.imag * cuu
        cap = seeds[k][2]
        ck = c[k] + cap
        out.append(AxisLine(np.array([ck.real, ck.imag]), dk.real / dk.imag, (nl, nr),
                            math.sqrt(max(res2, 0.0) / (nl + nr)), sv / (nl + nr) + cap.imag,
                            np.array([cap.real, cap.imag])))
    return out


_EVEN = 2 * np.arange(8)      # a view's first group (its left side), for up to 8 views
_IDS = np.arange(16)[:, None]  # the groups, as a column


def _side_points(rig: StereoRig, side: str, mask: np.ndarray, origin, tip, to_radii: float, width_tol: float,
                 min_points: int):
    """The edge crossings around one view's finger behind the cap, rectified: ``(r, d, cap, p)`` with
    the cap radius ``r``, the detector's axis direction ``d`` and cap centre ``cap`` in the rectified
    view (complex) and the crossings ``p`` about ``cap`` (complex); or a reason why there are too few."""
    r = float(tip.cap_radius_px if tip.cap_radius_px > 0 else tip.radius_px)
    u, v = tip.uv.tolist() if isinstance(tip.uv, np.ndarray) else (float(tip.uv[0]), float(tip.uv[1]))
    d0x, d0y = tip.direction.tolist() if isinstance(tip.direction, np.ndarray) else tip.direction
    # the crossings of the mask around the finger's first to_radii + 1 radii behind the centre
    cx, cy = u - origin[0], v - origin[1]
    ex, ey = cx + (to_radii + 1.0) * r * d0x, cy + (to_radii + 1.0) * r * d0y
    m = r * (1.0 + width_tol) + 2.0
    mh, mw = mask.shape
    x0, y0 = max(int(min(cx, ex) - m), 0), max(int(min(cy, ey) - m), 0)
    x1, y1 = min(int(max(cx, ex) + m) + 2, mw), min(int(max(cy, ey) + m) + 2, mh)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return f"the finger behind the cap is outside the {side} view's mask"
    # the cap centre, a point on the detector's axis and the crossings, rectified in one call (all
    # the crop's crossings: the fit's own band about the rectified axis picks the sides' points, and
    # the crop spans that band about the detector's axis with a margin of 2 px)
    z = np.concatenate(((u + 1j * v, u + 2.0 * r * d0x + 1j * (v + 2.0 * r * d0y)),
                        _inner_crossings(mask[y0:y1, x0:x1]) + complex(x0 + origin[0], y0 + origin[1])))
    if len(z) < 2 + 2 * min_points:
        return f"{len(z) - 2} edge points behind the cap in the {side} view"
    rect = rig.rectify_points_fast(z.view(np.float64).reshape(-1, 2), side).view(complex).ravel()
    cap = complex(rect[0])
    d = rect[1] - cap
    d /= abs(d) + 1e-12
    return r, complex(d), cap, rect[2:] - cap


def _inner_crossings(crop: np.ndarray) -> np.ndarray:
    """The midpoints (complex, column + i·row) between horizontally/vertically adjacent pixels of ``crop``
    of which one is skin and one not, leaving out those on the crop's border rows and columns (the
    crop's, not the finger's): the edge crossings inside the crop, horizontal ones first, each kind
    in row-major order."""
    b = crop > 0
    h, w = b.shape
    gh, gv = _crossing_grids(w, 1 << max(h - 1, 31).bit_length())
    return np.concatenate((gh[(b[1:-1, 1:] != b[1:-1, :-1]).ravel().nonzero()[0]],
                           gv[(b[1:, 1:-1] != b[:-1, 1:-1]).ravel().nonzero()[0]]))


@lru_cache(maxsize=512)
def _crossing_grids(w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the inner edge crossings between horizontal, and between vertical, neighbours of a crop
    ``w`` pixels wide can lie, in row-major order of their flags, for crops up to ``h`` rows (a
    crop of fewer rows takes the start): the coordinates without the arithmetic of each call."""
    hy, hx = np.mgrid[1:h - 1, 0:w - 1]
    vy, vx = np.mgrid[0:h - 1, 1:w - 1]
    return (hx + 0.5 + 1j * hy).ravel(), (vx + 1j * (vy + 0.5)).ravel()


def axis_disparity(line_l: AxisLine, line_r: AxisLine, v_ref: float) -> float:
    """Disparity of the axis's point on the rectified row ``v_ref`` (one epipolar plane)."""
    return line_l.u_at(v_ref) - line_r.u_at(v_ref)


class AxisLevel:
    """The side-edge axis's offset from the cap fits' disparity, followed over time.

    Each refined pair adds its offset ``axis − cap`` (px); the level is their exponentially weighted
    mean over ``tau_s`` (a finger's shape and slant change over seconds, the fits' noise from frame to
    frame), shrunk towards no offset by the prior ``N(0, prior_sigma_px²)`` while few pairs are in.
    :meth:`blend` gives the pair's disparity from the axis less the level and the cap fits, weighed by
    their variances — the axis's (``axis_sigma_px``), the cap fits' (``cap_sigma_px``) and the level's
    own: at the first pair about the plain mean of the two, the inverse-variance weight once the level
    is known. The level uses only the pairs before the current one."""

    def __init__(self, tau_s: float, axis_sigma_px: float, cap_sigma_px: float, prior_sigma_px: float):
        if not (tau_s > 0 and axis_sigma_px > 0 and cap_sigma_px > 0 and prior_sigma_px > 0):
            raise ValueError(f"AxisLevel: expected tau_s, axis_sigma_px, cap_sigma_px and prior_sigma_px > 0, "
                             f"got {tau_s!r}, {axis_sigma_px!r}, {cap_sigma_px!r}, {prior_sigma_px!r}")
        self.tau_s = float(tau_s)
        self._va, self._vc = float(axis_sigma_px) ** 2, float(cap_sigma_px) ** 2
        self._p0 = 1.0 / float(prior_sigma_px) ** 2  # the prior's precision (1/px²)
        self.reset()

    def reset(self) -> None:
        self._s0 = self._s1 = self._s2 = 0.0  # Σw, Σw·offset, Σw²
        self._t: float | None = None

    def _data_precision(self) -> float:
        """What the pairs so far tell of the level (1/px²): their effective count ``(Σw)² / Σw²`` over
        the variance of one offset (the axis's and the cap fits' together)."""
        return self._s0 * self._s0 / self._s2 / (self._va + self._vc) if self._s0 > 0 else 0.0

    @property
    def level_px(self) -> float:
        """The axis's offset from the cap fits (px): the pairs' weighted mean, shrunk towards 0 by the prior."""
        if self._s0 <= 0:
            return 0.0
        d = self._data_precision()
        return d * (self._s1 / self._s0) / (d + self._p0)

    @property
    def level_var_px2(self) -> float:
        """The level's variance (px²)."""
        return 1.0 / (self._data_precision() + self._p0)

    def axis_weight(self) -> float:
        """The axis's share of the pair's disparity: its variance with the level's against the cap fits'."""
        return self._vc / (self._vc + self._va + self.level_var_px2)

    def blend(self, axis_px: float, cap_px: float) -> float:
        """The pair's disparity from the axis's and the cap fits' (px)."""
        w = self.axis_weight()
        return w * (axis_px - self.level_px) + (1.0 - w) * cap_px

    def add(self, t: float, offset_px: float) -> None:
        """One pair's ``axis − cap`` at time ``t`` (s)."""
        d = 0.0 if self._t is None else math.exp(-max(t - self._t, 0.0) / self.tau_s)
        self._s0 = d * self._s0 + 1.0
        self._s1 = d * self._s1 + offset_px
        self._s2 = d * d * self._s2 + 1.0
        self._t = t
