"""Stereo 3-D of the fingertip (VisHap §2.1: "The position of the tracked fingertip is computed in
the coordinate system of the left camera frame by combining calculated disparity image and the
camera parameters").

The default is *sparse*: the two tracked tips (raw pixels) are mapped into the rectified images,
checked against the epipolar constraint (same rectified row within ``max_epipolar_px``) and the
disparity limits of the working volume, and triangulated through the rig's ``Q`` matrix. The
covariance follows from first-order propagation of an isotropic pixel noise ``sigma_px`` on the
four rectified coordinates.

The richer alternative of the paper, a dense disparity image (OpenCV StereoBM / StereoSGBM on the
rectified pair) sampled at the left tip, is :func:`dense_tip`; ``vishap bench vision`` charts both.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from vishap._core.errors import ConfigError, VisionError
from vishap.vision.axis_disparity import AxisLevel, axis_disparity, axis_lines
from vishap.vision.rig import StereoRig

__all__ = ["StereoPoint", "StereoConfig", "triangulate_tip", "with_covariance", "dense_tip", "DenseMatcher", "RefineConfig",
           "RefinedPair", "refine_tip_pair", "subpixel_cap_edges", "fit_circles_shared_row"]


@dataclass(frozen=True)
class StereoConfig:
    max_epipolar_px: float = 2.0   # |v_left − v_right| after rectification
    min_depth_m: float = 0.15      # disparity limits from the working depth range
    max_depth_m: float = 2.0
    sigma_px: float = 0.35         # pixel noise of one tip estimate (for the covariance)


@dataclass
class StereoPoint:
    ok: bool
    p_cam: np.ndarray | None = None       # (3,) metres, left camera frame
    cov_cam: np.ndarray | None = None     # (3, 3) m²
    disparity_px: float = float("nan")
    epipolar_px: float = float("nan")
    reason: str = ""
    rect: tuple | None = None             # the rectified pixels (left, right), when cov_cam was left out

    def __bool__(self) -> bool:
        return self.ok


def _disparity_limits(rig: StereoRig, cfg: StereoConfig) -> tuple[float, float]:
    fb = rig.rectified_fx_px * abs(rig.rectified_baseline_m)
    return fb / cfg.max_depth_m, fb / cfg.min_depth_m


def _pixel(p) -> tuple[float, float]:
    """A pixel (a (2,) array or a pair of numbers) as two floats."""
    u, v = p.tolist() if isinstance(p, np.ndarray) else p
    return float(u), float(v)


def triangulate_tip(rig: StereoRig, uv_left, uv_right, config: StereoConfig = StereoConfig()) -> StereoPoint:
    """Triangulate one tip from raw (distorted) pixels of the left and right image."""
    if uv_left is None or uv_right is None:
        return StereoPoint(False, reason="tip missing in one view")
    rl = rig.rectify_points(np.asarray(uv_left, dtype=np.float64).reshape(1, 2), "left")[0]
    rr = rig.rectify_points(np.asarray(uv_right, dtype=np.float64).reshape(1, 2), "right")[0]
    return triangulate_rectified_tip(rig, rl, rr, config)


_J_S = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.5], [1.0, 0.0, -1.0, 0.0]])  # ds/d(ul, vl, ur, vr): s = (u, v, d)


def triangulate_rectified_tip(rig: StereoRig, rl, rr, config: StereoConfig = StereoConfig(), *,
                              covariance: bool = True) -> StereoPoint:
    """As :func:`triangulate_tip`, for pixels already in the rectified images. ``covariance=False``
    leaves ``cov_cam`` out and keeps the pixels in ``rect`` (a check of a pair whose point is
    then replaced; :func:`with_covariance` adds it, the same floats)."""
    (ul, vl), (ur, vr) = rl, rr = _pixel(rl), _pixel(rr)
    epi = abs(vl - vr)
    disp = ul - ur
    dmin, dmax = _disparity_limits(rig, config)
    if not math.isfinite(epi) or epi > config.max_epipolar_px:
        return StereoPoint(False, disparity_px=disp, epipolar_px=epi, reason=f"epipolar error {epi:.2f} px")
    if not (dmin <= (disp if rig.rectified_baseline_m > 0 else -disp) <= dmax):
        return StereoPoint(False, disparity_px=disp, epipolar_px=epi,
                           reason=f"disparity {disp:.1f} px outside [{dmin:.1f}, {dmax:.1f}]")
    v = 0.5 * (vl + vr)
    # Q · (u, v, d, 1) and its division in floats (the same floats as the array product)
    h0, h1, h2, h3 = (a * ul + b * v + c * disp + e for a, b, c, e in rig.Q_rows)
    if h3 == 0.0:  # a rectification whose zero disparity is not at infinity (Q[3, 3] ≠ 0) puts this one there
        return StereoPoint(False, disparity_px=disp, epipolar_px=epi, reason=f"disparity {disp:.1f} px is at infinity")
    p_rect = np.array([h0 / h3, h1 / h3, h2 / h3])
    R1 = rig.R1
    if not covariance:
        return StereoPoint(True, p_cam=R1.T @ p_rect, disparity_px=disp, epipolar_px=epi, rect=(rl, rr))
    J_p = (rig.Q[:3, :3] - p_rect[:, None] * rig.Q[3, :3]) / h3  # dp/d(u, v, d) (the outer product)
    J = J_p @ _J_S
    cov_rect = (config.sigma_px ** 2) * (J @ J.T)
    p_cam = R1.T @ p_rect
    cov_cam = R1.T @ cov_rect @ R1
    return StereoPoint(True, p_cam=p_cam, cov_cam=cov_cam, disparity_px=disp, epipolar_px=epi)


def with_covariance(rig: StereoRig, sp: StereoPoint, config: StereoConfig = StereoConfig()) -> StereoPoint:
    """``sp`` with its covariance: a point triangulated with ``covariance=False`` triangulated again
    from its rectified pixels (the same ``config``); any other point as it is."""
    if not sp.ok or sp.cov_cam is not None or sp.rect is None:
        return sp
    return triangulate_rectified_tip(rig, *sp.rect, config)


class DenseMatcher:
    """Dense disparity (StereoBM or StereoSGBM) of a rectified pair, optionally in a band of rows."""

    def __init__(self, rig: StereoRig, method: str = "sgbm", *, block: int = 7, config: StereoConfig = StereoConfig()):
        dmin, dmax = _disparity_limits(rig, config)
        ndisp = int(np.ceil(dmax / 16.0)) * 16
        self.rig, self.method, self.config = rig, method, config
        if method == "bm":
            self.matcher = cv2.StereoBM_create(numDisparities=ndisp, blockSize=max(5, block | 1))
        elif method == "sgbm":
            b = max(3, block | 1)
            self.matcher = cv2.StereoSGBM_create(minDisparity=0, numDisparities=ndisp, blockSize=b,
                                                 P1=8 * 3 * b * b, P2=32 * 3 * b * b, uniquenessRatio=5,
                                                 mode=cv2.STEREO_SGBM_MODE_SGBM)
        else:
            raise ValueError(f"method: expected 'bm' or 'sgbm', got {method!r}")
        self.ndisp = ndisp

    def disparity(self, left_rect: np.ndarray, right_rect: np.ndarray) -> np.ndarray:
        if self.method == "bm":
            left_rect = cv2.cvtColor(left_rect, cv2.COLOR_BGR2GRAY) if left_rect.ndim == 3 else left_rect
            right_rect = cv2.cvtColor(right_rect, cv2.COLOR_BGR2GRAY) if right_rect.ndim == 3 else right_rect
        return self.matcher.compute(left_rect, right_rect).astype(np.float32) / 16.0


def dense_tip(matcher: DenseMatcher, left: np.ndarray, right: np.ndarray, uv_left, *, band_px: int = 24) -> StereoPoint:
    """3-D tip from a dense disparity map of the rows around the left tip (raw images in)."""
    rig = matcher.rig
    left_r = rig.rectify_image(left, "left")
    right_r = rig.rectify_image(right, "right")
    rl = rig.rectify_points(np.asarray(uv_left, dtype=np.float64).reshape(1, 2), "left")[0]
    v = int(round(rl[1]))
    y0, y1 = max(0, v - band_px), min(left_r.shape[0], v + band_px + 1)
    disp = matcher.disparity(left_r[y0:y1], right_r[y0:y1])
    u = int(round(rl[0]))
    if not (0 <= u < disp.shape[1]) or not (y0 <= v < y1):
        return StereoPoint(False, reason="tip outside the image")
    win = disp[v - y0 - 1: v - y0 + 2, max(0, u - 1): u + 2]
    good = win[win > 0]
    if good.size == 0:
        return StereoPoint(False, reason="no valid disparity at the tip")
    d = float(np.median(good))
    return triangulate_rectified_tip(rig, rl, np.array([rl[0] - d, rl[1]]), matcher.config)


# ---------------------------------------------------------------------------------------------
# Stereo refinement of a matched pair of cap centres
#
# The two cap circles are fitted independently on binary skin masks, whose edge crossings sit on a
# half-pixel grid: each centre is off by 0.2–0.3 px, and the disparity (their difference) by as
# much again, which is 2–3 mm of depth at 0.55 m (z²/(f·B) ≈ 9 mm per pixel). The refinements
# below use more of the silhouette (the finger's side edges) or the images themselves, in the
# rectified geometry where the tip lies on one row.

@dataclass(frozen=True)
class RefineConfig:
    """Stereo refinement of the cap centres (:func:`refine_tip_pair`).

    ``method``: ``"none"`` (the masks' cap fits alone); ``"axis"`` (the pipeline's default) — the
    disparity of the finger's axis from its two side edges behind the cap on the views' skin masks,
    on one rectified row (:mod:`vishap.vision.axis_disparity`), blended with the cap fits' disparity —
    levelled on them over ``axis_level_s`` and weighed by the fits' noise (``AxisLevel``; 0: the fixed
    ``axis_weight`` mean); ``"edges"`` — the cap's silhouette
    located to a fraction of a pixel in each image (colour profiles across the edge) and one circle
    pair fitted to both views with a shared rectified row and radius; ``"edges_separate"`` — the
    same edges, a circle per view; ``"match"`` — ZNCC of the left cap patch along the right
    rectified row, sub-pixel by a parabola (``match_masked``: only the template's inscribed disk
    counts). The image methods are options: on anti-aliased pairs the edges recover the disparity
    to a few hundredths of a pixel, but on the renderer's pixel-quantised silhouettes they are worse
    than the masks, and the match measures the finger's surface, in front of the cap's centre
    (docs/vision.md, "3-D fingertip accuracy").
    """

    method: str = "none"
    rays: int = 31                  # profiles across the cap's edge, spread over span_deg around the front
    span_deg: float = 180.0         # the cap in front of its centre
    half_width_px: float = 3.0      # each profile runs ± this across the expected edge
    step_px: float = 0.25
    min_contrast: float = 15.0      # finger against background, colour distance (0…441) along a profile
    max_shift_px: float = 1.5       # a refined centre further than this from the mask's fit is rejected
    core_deg: float = 90.0          # the first circle uses the edge points within this angle of the front
    max_residual_px: float = 1.0    # edge points further than this from a view's circle are dropped
    min_points: int = 8             # edge points needed per view
    match_search_px: int = 3        # "match": disparity searched ± this around the masks' disparity
    match_masked: bool = False
    axis_from_radii: float = 0.1    # "axis": side-edge points from this many cap radii behind the cap centre …
    axis_to_radii: float = 1.5      # … to this many (the first joint, 2 radii behind, widens the finger before it)
    axis_max_tilt_deg: float = 60.0  # a finger within 90° − this of the rows is refused (a line along a
    #   rectified row has no disparity of its own on that row)
    axis_width_tol: float = 0.3     # an edge point must lie a cap radius from the axis within this fraction
    axis_min_points: int = 4        # edge points needed on each side of the finger, per view
    axis_max_residual_px: float = 0.75  # an edge point this far from its fitted line is dropped
    axis_weight: float = 0.5        # without a level (axis_level_s 0): the axis's share of the pair's disparity,
    #   the rest from the cap fits
    axis_level_s: float = 3.0       # the axis's offset from the cap fits followed over this time constant and taken
    #   off (axis_disparity.AxisLevel; 0: off, the fixed axis_weight mean); the shares then come from …
    axis_sigma_px: float = 0.16     # … the noise of the axis's disparity and …
    cap_sigma_px: float = 0.25      # … the cap fits' (their spread about their means on wall 1 and button 2),
    axis_prior_px: float = 0.15     # … and the level's prior σ about no offset (the axis's offsets on the renders: 0.07–0.17 px)
    axis_at_cap: bool = False       # the axis's disparity at the cap centre's row (extrapolated) instead of at
    #   the mean row of its edge points, where the line is best known (a point 0.6–0.9 radii behind the cap)

    def __post_init__(self) -> None:
        if self.method not in ("none", "edges", "edges_separate", "match", "axis"):
            raise VisionError(f"refine method: expected none, edges, edges_separate, match or axis, got {self.method!r}")
        if not (isinstance(self.axis_level_s, (int, float)) and 0.0 <= self.axis_level_s < math.inf):
            raise ConfigError(f"expected a time constant ≥ 0 s (0: no level), got {self.axis_level_s!r}",
                              field="refine.axis_level_s")
        for name in ("axis_sigma_px", "cap_sigma_px", "axis_prior_px"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 < v < math.inf):
                raise ConfigError(f"expected a noise σ > 0 px, got {v!r}", field=f"refine.{name}")


@dataclass
class RefinedPair:
    ok: bool
    uv_left: np.ndarray | None = None      # raw pixels
    uv_right: np.ndarray | None = None
    radius_px: float = 0.0                 # rectified radius of the circle pair ("edges")
    points: tuple[int, int] = (0, 0)       # edge points used per view
    reason: str = ""
    rect_left: tuple[float, float] | None = None  # the same pixels in the rectified images, where the method has them
    rect_right: tuple[float, float] | None = None
    axis_offset_px: float | None = None    # "axis": the axis's disparity less the cap fits' (what AxisLevel follows)


def _unrectify_points(rig: StereoRig, pts: np.ndarray, side: str) -> np.ndarray:
    """Rectified pixels of one view back to its raw (distorted) pixels (N, 2)."""
    K, d, Rr, P = ((rig.K_left, rig.dist_left, rig.R1, rig.P1) if side == "left"
                   else (rig.K_right, rig.dist_right, rig.R2, rig.P2))
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    x = (pts[:, 0] - P[0, 2]) / P[0, 0]
    y = (pts[:, 1] - P[1, 2]) / P[1, 1]
    rays = np.column_stack([x, y, np.ones(len(pts))]) @ Rr  # Rr^T applied to row vectors
    if not np.any(d) and K[0, 1] == 0.0:
        # no distortion: cv2.projectPoints' own arithmetic (times the reciprocal depth, then f·x + c; it
        # has no skew), the same floats without its call's overhead
        iz = 1.0 / rays[:, 2]
        return np.column_stack([rays[:, 0] * iz * K[0, 0] + K[0, 2], rays[:, 1] * iz * K[1, 1] + K[1, 2]])
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, d)
    return out.reshape(-1, 2)


_FAN: dict = {}


def _fan(n: int, span_deg: float) -> np.ndarray:
    key = (n, span_deg)
    if key not in _FAN:
        a = np.deg2rad(np.linspace(-span_deg / 2, span_deg / 2, n))
        _FAN[key] = np.column_stack([np.cos(a), np.sin(a)])
    return _FAN[key]


def subpixel_cap_edges(image: np.ndarray, centre, radius: float, direction, config: RefineConfig = RefineConfig()
                       ) -> np.ndarray:
    """Points of the cap's silhouette (N, 2 raw pixels) located to a fraction of a pixel.

    Profiles run along rays from ``centre`` over the cap in front of it (opposite ``direction``,
    the unit vector into the finger), across the expected edge at ``radius``. Each profile's colours
    are projected on the line from its inner (finger) end to its outer (background) end; the edge
    is where the projection crosses half-way — for any symmetric blur of the edge (defocus, motion,
    anti-aliasing) the geometric edge, whatever the two colours are. Profiles with too little
    contrast, or without a single crossing, are skipped."""
    c = np.asarray(centre, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    front = -d / max(np.hypot(*d), 1e-12)
    rot = np.array([[front[0], -front[1]], [front[1], front[0]]])
    rays = _fan(config.rays, config.span_deg) @ rot.T                      # (R, 2) unit rays
    s = np.arange(-config.half_width_px, config.half_width_px + 1e-9, config.step_px) + radius  # (S,)
    s = s[s > 0.5]
    if s.size < 8:
        return np.empty((0, 2))
    pts = c[None, None, :] + rays[:, None, :] * s[None, :, None]           # (R, S, 2)
    # a float crop around the cap, sampled bilinearly at the profile points
    h, w = image.shape[:2]
    m = radius + config.half_width_px + 2
    x0, y0 = int(max(0, np.floor(c[0] - m))), int(max(0, np.floor(c[1] - m)))
    x1, y1 = int(min(w, np.ceil(c[0] + m) + 1)), int(min(h, np.ceil(c[1] + m) + 1))
    if x1 - x0 < 4 or y1 - y0 < 4:
        return np.empty((0, 2))
    crop = image[y0:y1, x0:x1].astype(np.float32)
    mx = (pts[..., 0] - x0).astype(np.float32)
    my = (pts[..., 1] - y0).astype(np.float32)
    prof = cv2.remap(crop, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    if prof.ndim == 2:
        prof = prof[..., None]
    inside = (mx >= 0) & (mx <= x1 - x0 - 1) & (my >= 0) & (my <= y1 - y0 - 1)
    inner = prof[:, :3].mean(axis=1)
    outer = prof[:, -3:].mean(axis=1)
    diff = outer - inner                                                   # (R, C)
    n2 = (diff * diff).sum(axis=1)
    p = np.einsum("rsc,rc->rs", prof - inner[:, None, :], diff) / np.maximum(n2, 1e-9)[:, None]
    above = p >= 0.5
    cross = above[:, 1:] != above[:, :-1]
    single = cross.sum(axis=1) == 1
    ok = single & (n2 >= config.min_contrast ** 2) & inside.all(axis=1)
    if not ok.any():
        return np.empty((0, 2))
    k = np.argmax(cross, axis=1)
    r_idx = np.flatnonzero(ok)
    k = k[r_idx]
    p0, p1 = p[r_idx, k], p[r_idx, k + 1]
    frac = (0.5 - p0) / (p1 - p0)
    s_edge = s[k] + frac * (s[k + 1] - s[k])
    return c[None, :] + rays[r_idx] * s_edge[:, None]


def fit_circles_shared_row(pts_left: np.ndarray, pts_right: np.ndarray, *, iterations: int = 6):
    """Geometric least-squares fit of two circles with one centre row and one radius (a sphere's
    outline in a rectified pair: same row, same size): ``(u_left, u_right, v, r)`` or None."""
    from vishap.vision.fingertip import fit_circle

    fl, fr = fit_circle(pts_left), fit_circle(pts_right)
    if fl is None or fr is None:
        return None
    theta = np.array([fl[0][0], fr[0][0], 0.5 * (fl[0][1] + fr[0][1]), 0.5 * (fl[1] + fr[1])])
    pts = np.vstack([pts_left, pts_right])
    is_r = np.r_[np.zeros(len(pts_left), bool), np.ones(len(pts_right), bool)]
    for _ in range(iterations):
        u = np.where(is_r, theta[1], theta[0])
        dx, dy = pts[:, 0] - u, pts[:, 1] - theta[2]
        rho = np.maximum(np.hypot(dx, dy), 1e-9)
        res = rho - theta[3]
        J = np.zeros((len(pts), 4))
        J[~is_r, 0] = -dx[~is_r] / rho[~is_r]
        J[is_r, 1] = -dx[is_r] / rho[is_r]
        J[:, 2] = -dy / rho
        J[:, 3] = -1.0
        step, *_ = np.linalg.lstsq(J, -res, rcond=None)
        theta = theta + step
        if np.max(np.abs(step)) < 1e-6:
            break
    return theta if np.all(np.isfinite(theta)) else None


def refine_tip_pair(rig: StereoRig, left: np.ndarray, right: np.ndarray, tip_left, tip_right,
                    config: RefineConfig = RefineConfig(), *, masks: dict | None = None,
                    level: AxisLevel | None = None) -> RefinedPair:
    """Refine a matched pair of cap centres (``Fingertip`` results in raw pixels: ``uv``,
    ``cap_radius_px``, ``direction``) on the images; see :class:`RefineConfig`. ``masks``
    (method ``"axis"``): per view ``(skin mask, raw pixel of its (0, 0))``; ``level``: the axis's
    offset from the cap fits so far (:class:`~vishap.vision.axis_disparity.AxisLevel`; None: the
    fixed ``axis_weight`` mean). The level is read, not updated: the caller adds the pair it keeps."""
    if config.method == "none":
        return RefinedPair(False, reason="no refinement")
    if config.method == "match":
        return _refine_by_match(rig, left, right, tip_left, tip_right, config)
    if config.method == "axis":
        return _refine_by_axis(rig, masks, tip_left, tip_right, config, level)
    from vishap.vision.fingertip import fit_circle

    pts = {}
    for side, img, tip in (("left", left, tip_left), ("right", right, tip_right)):
        radius = tip.cap_radius_px if tip.cap_radius_px > 0 else tip.radius_px
        edge = subpixel_cap_edges(img, tip.uv, radius, tip.direction, config)
        edge = _cap_points(edge, tip.uv, tip.direction, config)
        if edge is None:
            return RefinedPair(False, reason=f"too few sub-pixel edge points on a circle in the {side} view")
        pts[side] = rig.rectify_points(edge, side)
    rect0 = {s: rig.rectify_points(np.asarray(t.uv, dtype=np.float64).reshape(1, 2), s)[0]
             for s, t in (("left", tip_left), ("right", tip_right))}
    if config.method == "edges":
        th = fit_circles_shared_row(pts["left"], pts["right"])
        res = None if th is None else (np.array([th[0], th[2]]), np.array([th[1], th[2]]), th[3])
    else:
        fl, fr = fit_circle(pts["left"]), fit_circle(pts["right"])
        res = None if fl is None or fr is None else (fl[0], fr[0], 0.5 * (fl[1] + fr[1]))
    if res is None:
        return RefinedPair(False, reason="no circle fits the sub-pixel edges")
    cl, cr, r = res
    shift = max(np.hypot(*(cl - rect0["left"])), np.hypot(*(cr - rect0["right"])))
    if not shift <= config.max_shift_px:
        return RefinedPair(False, reason=f"refined centre {shift:.2f} px from the mask's fit")
    return RefinedPair(True, _unrectify_points(rig, cl, "left")[0], _unrectify_points(rig, cr, "right")[0],
                       float(r), (len(pts["left"]), len(pts["right"])))


def _refine_by_axis(rig: StereoRig, masks: dict | None, tip_left, tip_right, config: RefineConfig,
                    level: AxisLevel | None = None) -> RefinedPair:
    """The pair's disparity from the finger's side edges (:mod:`vishap.vision.axis_disparity`): each
    view's axis line at the cap centres' mean rectified row, blended with the cap fits' disparity
    (by ``level`` when given, else the fixed ``axis_weight``); the left point is the cap centre's."""
    if masks is None:
        raise VisionError("refine method 'axis' needs the skin masks of both views")
    lines = axis_lines(rig, [("left", *masks["left"], tip_left), ("right", *masks["right"], tip_right)],
                       from_radii=config.axis_from_radii, to_radii=config.axis_to_radii,
                       max_tilt_deg=config.axis_max_tilt_deg, width_tol=config.axis_width_tol,
                       max_residual_px=config.axis_max_residual_px, min_points=config.axis_min_points)
    if isinstance(lines[0], str):
        return RefinedPair(False, reason=lines[0])
    ll, lr = lines
    cl, cr = ll.cap, lr.cap
    v = 0.5 * float(cl[1] + cr[1])
    cap = float(cl[0] - cr[0])
    axis = axis_disparity(ll, lr, v if config.axis_at_cap else 0.5 * (ll.v_mean + lr.v_mean))
    if not abs(axis - cap) <= config.max_shift_px:
        return RefinedPair(False, reason=f"axis disparity {axis - cap:+.2f} px from the cap fits'")
    disp = level.blend(axis, cap) if level is not None else config.axis_weight * axis + (1.0 - config.axis_weight) * cap
    ul, ur = float(cl[0]), float(cl[0]) - disp
    return RefinedPair(True, _unrectify_point(rig, ul, v, "left"), _unrectify_point(rig, ur, v, "right"), 0.0,
                       (sum(ll.points), sum(lr.points)), rect_left=(ul, v), rect_right=(ur, v),
                       axis_offset_px=axis - cap)


def _unrectify_point(rig: StereoRig, u: float, v: float, side: str) -> np.ndarray:
    """One rectified pixel back to raw pixels (2,): :func:`_unrectify_points`' arithmetic in plain floats
    for a view without distortion (two per refined pair: the arrays' overhead was most of their cost)."""
    view = rig.rectified_view(side)
    if not (view.undistorted and view.skew_free):
        return _unrectify_points(rig, (u, v), side)[0]
    return np.array(view.unrectify(u, v))


def _cap_points(edge: np.ndarray, centre, direction, config: RefineConfig) -> np.ndarray | None:
    """The edge points that lie on the cap's circle: a first circle through the points within
    ``core_deg`` of the front (the finger's sides and a wrong direction estimate leave the
    circle towards the fan's ends), then every point within ``max_residual_px`` of it, twice."""
    from vishap.vision.fingertip import fit_circle

    if len(edge) < config.min_points:
        return None
    d = np.asarray(direction, dtype=np.float64)
    rel = edge - np.asarray(centre, dtype=np.float64)
    cosang = -(rel @ d) / np.maximum(np.hypot(rel[:, 0], rel[:, 1]) * max(np.hypot(*d), 1e-12), 1e-12)
    keep = cosang >= np.cos(np.deg2rad(config.core_deg))
    for _ in range(3):
        if keep.sum() < config.min_points:
            return None
        fit = fit_circle(edge[keep])
        if fit is None:
            return None
        keep = np.abs(np.hypot(*(edge - fit[0]).T) - fit[1]) <= config.max_residual_px
    return edge[keep] if keep.sum() >= config.min_points else None


def _rectified_patch(rig: StereoRig, image: np.ndarray, side: str, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """The rectified image of one view over the rectified pixels [x0, x1) × [y0, y1) (float32 grey)."""
    m1, m2 = rig.rectification_maps(side)
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    return cv2.remap(grey, m1[y0:y1, x0:x1], m2[y0:y1, x0:x1], cv2.INTER_LINEAR).astype(np.float32)


def _refine_by_match(rig, left, right, tip_left, tip_right, config: RefineConfig) -> RefinedPair:
    """ZNCC of the left cap patch (rectified) along the right rectified row, parabola peak."""
    rl = rig.rectify_points(np.asarray(tip_left.uv, dtype=np.float64).reshape(1, 2), "left")[0]
    rr = rig.rectify_points(np.asarray(tip_right.uv, dtype=np.float64).reshape(1, 2), "right")[0]
    radius = max(tip_left.cap_radius_px, tip_left.radius_px)
    half = int(np.ceil(radius + 2))
    w, h = rig.image_size
    xl, yl = int(round(rl[0])), int(round(rl[1]))
    d0 = int(round(rl[0] - rr[0]))
    S = config.match_search_px
    x0, y0 = xl - half, yl - half
    if x0 < 0 or y0 < 0 or xl + half + 1 > w or yl + half + 1 > h or x0 - d0 - S < 0 or xl + half + 1 - d0 + S > w:
        return RefinedPair(False, reason="cap patch at the image border")
    templ = _rectified_patch(rig, left, "left", x0, y0, xl + half + 1, yl + half + 1)
    band = _rectified_patch(rig, right, "right", x0 - d0 - S, y0, xl + half + 1 - d0 + S, yl + half + 1)
    if config.match_masked:
        from vishap.vision.fingertip import _disk

        mask = cv2.resize(_disk(half), templ.shape[::-1], interpolation=cv2.INTER_NEAREST).astype(np.float32)
        score = cv2.matchTemplate(band, templ, cv2.TM_CCOEFF_NORMED, mask=mask)[0]
    else:
        score = cv2.matchTemplate(band, templ, cv2.TM_CCOEFF_NORMED)[0]
    k = int(np.argmax(score))
    if k == 0 or k == len(score) - 1 or not np.isfinite(score[k]):
        return RefinedPair(False, reason="no ZNCC peak inside the search range")
    a, b, c = score[k - 1], score[k], score[k + 1]
    den = a - 2 * b + c
    off = 0.5 * (a - c) / den if den < 0 else 0.0
    # the band starts at x0 − d0 − S: a match at index k means disparity d0 + S − k
    disp = d0 + S - (k + off)
    rr_new = np.array([rl[0] - disp, rl[1]])
    return RefinedPair(True, np.asarray(tip_left.uv, dtype=np.float64).copy(),
                       _unrectify_points(rig, rr_new, "right")[0], 0.0, (0, 0))
