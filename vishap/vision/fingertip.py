"""Fingertip detection on a skin mask (VisHap §2.1, "Fingertip Detection and Tracking", eq. 2).

The paper's pseudo-code, for every pixel p of the search region:

1. p must be skin;
2.–3. the expected fingertip radius is ``r = K / z`` (z: depth of the fingertip in the camera);
4.–5. every pixel of the filled circle C of radius r centred at p must be skin (``S_filled``
      equals the area of C);
6.–7. on the square S centred at p with half-side ``r2 = r + δr`` the number of skin pixels
      ``S_square`` must lie in ``[2·r2, 4·r2]`` (a finger of about the circle's width leaves the
      square on one side; the square's perimeter holds ``8·r2`` pixels, so the limits are a quarter
      and a half of it — the reading of Hardenberg & Bérard's test the paper cites);
8.–9. the number N of diagonally opposite pixel pairs of S that are both skin must be ≤ 1 (a
      point in the middle of a finger has skin on two opposite sides);
10. p is a candidate with ``score = S_filled``; the best score wins (ties: nearest to the
      predicted position, else farthest from the skin centroid — the hand's extremity).

The loop is vectorised: step 4–5 is one erosion by the disk (a pixel survives exactly when its
whole circle is skin); steps 6–9 gather the square's pixels of the surviving candidates at once.

Sub-pixel refinement (not in the paper): a least-squares circle through the mask's edge crossings
(midpoints between a skin and a non-skin neighbour) of the cap in front of the winning candidate;
its centre is the centre of the fingertip's hemispherical cap, the same 3-D point in both views,
which is what stereo triangulates.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

__all__ = ["FingertipConfig", "Fingertip", "detect_fingertip", "detect_fingertips", "square_ring_offsets", "fit_circle"]


@dataclass(frozen=True)
class FingertipConfig:
    """Detector settings. ``r = K / z`` is computed by the caller (pipeline) from the rig and tracker."""

    delta_r_frac: float = 0.8     # δr of the paper as a fraction of r: square half-side r2 = r + δr
    ring_min: float = 2.0         # S_square ≥ ring_min·r2   (paper: 2)
    ring_max: float = 4.0         # S_square ≤ ring_max·r2   (paper: 4)
    max_diagonal_pairs: int = 1   # reject when N > this     (paper: 1)
    fill_ratio: float = 1.0       # S_filled ≥ fill_ratio·area (paper: the whole circle)
    refine: bool = True


@dataclass
class Fingertip:
    """Result of one detection, in the image's pixels: the mask's own plus the ``origin`` given to
    :func:`detect_fingertips` (none: the mask's)."""

    found: bool
    uv: np.ndarray | None = None          # refined cap centre (float pixels)
    uv_pixel: np.ndarray | None = None    # the winning candidate pixel
    direction: np.ndarray | None = None   # unit vector from the tip into the finger (image)
    radius_px: float = 0.0                # r used
    cap_radius_px: float = 0.0            # radius of the fitted cap circle (0 when not refined)
    score: float = 0.0
    n_candidates: int = 0                 # candidates passing steps 1–9 (1: the nearest-first search stops at its first)
    extremity_px: float = 0.0             # distance from the skin centroid of the searched mask


@lru_cache(maxsize=64)
def square_ring_offsets(r2: int) -> np.ndarray:
    """(8·r2, 2) integer (dx, dy) offsets around a square of half-side r2, ordered so that
    offset ``i + 4·r2`` is the diagonal opposite ``-offset[i]``."""
    top = [(dx, -r2) for dx in range(-r2, r2)]
    right = [(r2, dy) for dy in range(-r2, r2)]
    half = np.array(top + right, dtype=np.intp)
    return np.concatenate([half, -half])


@lru_cache(maxsize=64)
def _ring_offsets_f(r2: int) -> np.ndarray:
    return square_ring_offsets(r2).astype(np.float64)


@lru_cache(maxsize=256)
def _flat_offsets(r2: int, width: int) -> np.ndarray:
    """:func:`square_ring_offsets` as offsets into a flattened mask ``width`` pixels wide."""
    off = square_ring_offsets(r2)
    return off[:, 1] * width + off[:, 0]


@lru_cache(maxsize=64)
def _rect(r2: int) -> np.ndarray:
    return np.ones((2 * r2 + 1, 2 * r2 + 1), np.uint8)


@lru_cache(maxsize=64)
def _disk(r: int) -> np.ndarray:
    yy, xx = np.mgrid[-r: r + 1, -r: r + 1]
    return ((xx * xx + yy * yy) <= r * r + 1e-9).astype(np.uint8)


@lru_cache(maxsize=64)
def _disk_area(r: int) -> int:
    return int(_disk(r).sum())


def detect_fingertip(mask: np.ndarray, r: float, config: FingertipConfig = FingertipConfig(),
                     *, prior_uv=None) -> Fingertip:
    """Find the fingertip in a binary skin ``mask`` (uint8, nonzero = skin) for radius ``r`` pixels."""
    tips = detect_fingertips(mask, r, config, prior_uv=prior_uv, max_tips=1)
    return tips[0] if tips else Fingertip(False, radius_px=float(r))


def detect_fingertips(mask: np.ndarray, r: float, config: FingertipConfig = FingertipConfig(),
                      *, prior_uv=None, max_tips: int = 4, origin=(0, 0)) -> list[Fingertip]:
    """All separate fingertip candidates (best first), at most ``max_tips``.

    Candidates are grouped: after the best one, candidates within ``2·r2`` of it are dropped, and
    so on. Order: score (the paper's), then distance to ``prior_uv`` when given, else distance
    from the skin centroid of the mask, farthest first (an extended finger is the hand's extremity).
    ``origin``: the image pixel of the mask's pixel (0, 0), for a mask of a region of an image;
    ``prior_uv`` and the pixels returned are then the image's.
    """
    ri = max(1, int(round(r)))
    r2 = max(ri + 1, int(round(r + config.delta_r_frac * r)))
    disk = _disk(ri)
    area = _disk_area(ri)
    bx, by, bw, bh = cv2.boundingRect(mask)
    if bw == 0:
        return []
    x0 = y0 = 0
    if bw * bh < mask.size // 2:  # work on the mask's bounding box (plus a margin) only
        x0, y0 = max(0, bx - r2), max(0, by - r2)
        x1, y1 = min(mask.shape[1], bx + bw + r2), min(mask.shape[0], by + bh + r2)
        if (x0, y0) != (0, 0) or (x1, y1) != mask.shape[::-1]:
            mask = np.ascontiguousarray(mask[y0:y1, x0:x1])
    ox, oy = origin
    prior = None if prior_uv is None else ((float(prior_uv[0]) - ox) - x0, (float(prior_uv[1]) - oy) - y0)
    return _detect(mask, r, config, prior, max_tips, ri, r2, disk, area, (x0, y0, ox, oy))


def _detect(mask, r, config, prior_uv, max_tips, ri, r2, disk, area, shift) -> list[Fingertip]:
    """:func:`detect_fingertips` on a mask cropped to its skin (plus ``r2``), ``prior_uv`` in its
    coordinates; ``shift = (x0, y0, ox, oy)``: the crop's corner in the mask given and that mask's
    origin, added in turn to the pixels returned."""
    h, w = mask.shape
    if h < 2 * r2 + 1 or w < 2 * r2 + 1:
        return []
    # steps 1, 4, 5: whole circle is skin; outside the mask counts as non-skin.
    nearest = prior_uv is not None and max_tips == 1 and config.fill_ratio >= 1.0
    if config.fill_ratio >= 1.0:
        cand = cv2.erode(mask, disk, borderType=cv2.BORDER_CONSTANT, borderValue=0)
        if not nearest:
            # Shortcut (exact): a pixel whose whole square of half-side r2 is skin has S_square = 8·r2,
            # which step 7 rejects, so those pixels (a palm's interior) are dropped before gathering
            # (the nearest-first search below tests few candidates and needs no second erosion)
            cand = cv2.subtract(cand, cv2.erode(mask, _rect(r2), borderType=cv2.BORDER_CONSTANT, borderValue=0))
        scores = None
    else:
        inner = cv2.erode(mask, _rect(r2), borderType=cv2.BORDER_CONSTANT, borderValue=0)
        cnt = cv2.filter2D((mask > 0).astype(np.float32), -1, disk.astype(np.float32),
                           borderType=cv2.BORDER_CONSTANT)
        cand = ((cnt >= config.fill_ratio * area - 1e-3) & (mask > 0) & (inner == 0)).view(np.uint8)
        scores = cnt
    # candidates lie r2 inside the mask (their square within it)
    pts = cv2.findNonZero(cand[r2:h - r2, r2:w - r2])
    if pts is None:
        return []
    pts = pts.reshape(-1, 2)
    xs = pts[:, 0] + r2
    ys = pts[:, 1] + r2
    # steps 6–9 on the square ring
    flat, off_flat = mask.ravel(), _flat_offsets(r2, w)
    if nearest:
        found = _nearest_candidate(flat, xs, ys, w, off_flat, r2, config, prior_uv)
        if found is None:
            return []
        k, ring_k = found
        return _tips(mask, r, config, r2, xs[k: k + 1], ys[k: k + 1], ring_k[None], float(area), None, [0], shift)

    if xs.size > _PREFILTER_MIN:  # many candidates (full frame): S_square of all from an integral image first
        ii = cv2.integral(cv2.threshold(mask, 0, 1, cv2.THRESH_BINARY)[1])
        s_square = _box_sum(ii, xs, ys, r2) - _box_sum(ii, xs, ys, r2 - 1)
        keep = (s_square >= config.ring_min * r2) & (s_square <= config.ring_max * r2)
        xs, ys = xs[keep], ys[keep]
    ring, keep = _ring_test(flat, ys * w + xs, off_flat, r2, config)
    xs, ys, ring = xs[keep], ys[keep], ring[keep]
    if xs.size == 0:
        return []
    score = float(area) if scores is None else scores[ys, xs].astype(np.float64)  # (scalar: all equal)
    # step 10: best score first; ties broken by the prior or by extremity
    if prior_uv is not None:
        ref = np.asarray(prior_uv, dtype=np.float64)
        tie = (xs - ref[0]) ** 2 + (ys - ref[1]) ** 2
        ext = None                  # (extremity not measured: 0)
    else:
        m = cv2.moments(mask, binaryImage=True)
        centroid = np.array([m["m10"], m["m01"]]) / max(m["m00"], 1.0)
        ext = np.hypot(xs - centroid[0], ys - centroid[1])
        tie = -ext
    if max_tips == 1:
        chosen = [int(np.argmin(tie - 1e9 * score))]
    else:
        order = np.lexsort((tie, -score)) if scores is not None else np.argsort(tie, kind="stable")
        alive = np.ones(xs.size, bool)
        chosen = []
        for k in order.tolist():
            if not alive[k]:
                continue
            chosen.append(k)
            if len(chosen) >= max_tips:
                break
            alive &= (xs - xs[k]) ** 2 + (ys - ys[k]) ** 2 > (2 * r2) ** 2
    return _tips(mask, r, config, r2, xs, ys, ring, score, ext, chosen, shift)


def _ring_test(flat, at, off_flat, r2, config):
    """Steps 6–9 for the candidates at the flat indices ``at`` of the mask ``flat``: ``(ring, ok)``,
    each one's square-ring skin flags (M, 8·r2) and whether its ring passes."""
    n_half = 4 * r2
    ring = flat[at[:, None] + off_flat] > 0
    s_square = _row_sums(ring)
    ok = (s_square >= config.ring_min * r2) & (s_square <= config.ring_max * r2) \
        & (_row_sums(ring[:, :n_half] & ring[:, n_half:]) <= config.max_diagonal_pairs)
    return ring, ok


def _nearest_candidate(flat, xs, ys, w, off_flat, r2, config, prior_uv):
    """Steps 6–9 for one tip near a prior (a tracking window): with every score equal the winner is
    the valid candidate nearest ``prior_uv`` (the first in the candidates' order among equally near
    ones), so candidates are tested in order of distance, a chunk at a time, up to the first valid
    one: ``(its index, its ring of skin flags)``, or None."""
    d2 = (xs - float(prior_uv[0])) ** 2 + (ys - float(prior_uv[1])) ** 2
    order = d2.argsort(kind="stable")
    at = ys * w + xs
    for k in range(0, order.size, 32):
        sel = order[k: k + 32]
        ring, ok = _ring_test(flat, at[sel], off_flat, r2, config)
        j = int(ok.argmax())
        if ok[j]:
            return int(sel[j]), ring[j]
    return None


def _tips(mask, r, config, r2, xs, ys, ring, score, ext, chosen, shift) -> list:
    """The chosen candidates as :class:`Fingertip` results, their cap circles fitted (``config.refine``);
    ``shift``: as :func:`_detect`'s (each offset added in turn, as floats: the same sums however the
    mask was cropped)."""
    # direction into the finger: the mean offset of each tip's skin ring pixels (sums of small
    # integers: exact in any order)
    ring_k = ring[chosen]
    d_all = ((ring_k @ _ring_offsets_f(r2)) / _row_sums(ring_k)[:, None]).tolist()
    corners = [(int(xs[k]), int(ys[k])) for k in chosen]
    dirs = []
    for dx, dy in d_all:
        nd = math.hypot(dx, dy)
        dirs.append(np.array([dx / nd, dy / nd]) if nd > 0 else np.array([0.0, 1.0]))
    fits = _refine_all(mask, corners, dirs, r2) if config.refine else [None] * len(chosen)
    x0, y0, ox, oy = shift
    tips = []
    for k, (px, py), d, fit in zip(chosen, corners, dirs, fits):
        u, v, cap = float(px), float(py), 0.0
        if fit is not None:
            (cu, cv), d, cap = fit
            u, v = u + cu, v + cv
        tips.append(Fingertip(True, uv=np.array([(u + x0) + ox, (v + y0) + oy]),
                              uv_pixel=np.array([float((px + x0) + ox), float((py + y0) + oy)]), direction=d,
                              radius_px=float(r), cap_radius_px=cap,
                              score=score if isinstance(score, float) else float(score[k]),
                              n_candidates=int(xs.size), extremity_px=0.0 if ext is None else float(ext[k])))
    return tips


_PREFILTER_MIN = 256  # candidates above which S_square comes from an integral image before the ring gather


def _box_sum(ii: np.ndarray, xs: np.ndarray, ys: np.ndarray, h: int) -> np.ndarray:
    """Sums over the squares of half-side ``h`` centred at (xs, ys), from the integral image ``ii``
    (its four corners taken by flat index: one index computation instead of four)."""
    w = ii.shape[1]
    flat = ii.ravel()
    top_left = (ys - h) * w + (xs - h)
    side = 2 * h + 1
    return (flat[top_left + (side * w + side)] - flat[top_left + side * w] - flat[top_left + side]
            + flat[top_left])


def fit_circle(pts: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Algebraic (Kåsa) least-squares circle through (N, 2) points: (centre, radius) or None."""
    n = len(pts)
    if n < 5:
        return None
    m = pts.sum(axis=0) / n
    q = pts - m  # centred: the sums stay small
    u, v = q[:, 0], q[:, 1]
    uu, vv = u * u, v * v
    fit = _kasa(n, u.sum(), v.sum(), uu.sum(), u @ v, vv.sum(), uu @ u, uu @ v, vv @ u, vv @ v)
    return None if fit is None else (np.array(fit[:2]) + m, fit[2])


@lru_cache(maxsize=64)
def _edge_grid(half: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the mask's edge crossings of a (2·half+1)² window centred on a pixel can lie, relative
    to that pixel: the midpoints between horizontally, then vertically adjacent pixels (each in
    row-major order), as ``(N, 2)`` offsets, the moments ``[1, u, v, u², uv, v², u³, u²v, uv², v³]``
    of each ``(N, 10)`` and ``u² + v²`` ``(N,)``. Every offset is a multiple of 0.5, so these values
    and weighted sums of the moments over any set of the points are exact (the circle fit's sums do
    not depend on the order of the points)."""
    a = np.arange(-half, half + 1, dtype=np.float64)
    hv, hu = np.meshgrid(a, a[:-1] + 0.5, indexing="ij")     # (W, W−1): between columns
    vv, vu = np.meshgrid(a[:-1] + 0.5, a, indexing="ij")     # (W−1, W): between rows
    u = np.concatenate([hu.ravel(), vu.ravel()])
    v = np.concatenate([hv.ravel(), vv.ravel()])
    mom = np.column_stack([np.ones_like(u), u, v, u * u, u * v, v * v, u ** 3, u * u * v, u * v * v, v ** 3])
    return np.column_stack([u, v]), mom, u * u + v * v


def _refine_all(mask: np.ndarray, corners: list, directions: list, r2: int) -> list:
    """Sub-pixel cap circles of the candidates at the whole pixels ``corners`` [(x, y), ...] (the
    ring's ``directions`` as the fallback of :func:`_finger_directions`), all at once: per candidate
    ``((cx, cy), direction, radius)`` with the centre relative to its pixel, or None. Per candidate:
    the mask's edge crossings in a window of half-side ``r2 + 4`` around its pixel, the finger's
    direction (:func:`_finger_directions`), then twice a circle through the crossings in front of the
    current centre (within ``r2 + 2.5`` of it). Each round fits every candidate from one product of
    the selected crossings with their moments (:func:`_kasa`). A candidate whose fit fails, moves
    its centre over ``r2 + 1`` px or grows over ``2·r2 + 2`` px keeps its pixel (None)."""
    h, w = mask.shape
    half = r2 + 4
    grid, mom, grid_r2 = _edge_grid(half)
    K = len(corners)
    inside = all(half <= x < w - half and half <= y < h - half for x, y in corners)
    if inside and K == 1:  # the tracked case: one window, a slice
        x, y = corners[0]
        win = mask[y - half: y + half + 1, x - half: x + half + 1] > 0
        nn = np.concatenate([(win[:, 1:] != win[:, :-1]).ravel(), (win[1:] != win[:-1]).ravel()]).nonzero()[0]
        kk = None
    else:
        pi = np.array(corners, dtype=np.intp)
        a = np.arange(-half, half + 1)
        X, Y = pi[:, :1] + a, pi[:, 1:] + a                              # (K, W) image columns / rows
        if inside:
            win = mask[Y[:, :, None], X[:, None, :]] > 0                 # (K, W, W)
        else:  # a window cut by the mask's border: crossings only between two pixels of the mask
            win = mask[np.clip(Y, 0, h - 1)[:, :, None], np.clip(X, 0, w - 1)[:, None, :]] > 0
            ok = ((Y >= 0) & (Y < h))[:, :, None] & ((X >= 0) & (X < w))[:, None, :]
        eh = win[:, :, 1:] != win[:, :, :-1]
        ev = win[:, 1:, :] != win[:, :-1, :]
        if not inside:
            eh &= ok[:, :, 1:] & ok[:, :, :-1]
            ev &= ok[:, 1:, :] & ok[:, :-1, :]
        kk, nn = np.nonzero(np.concatenate([eh.reshape(K, -1), ev.reshape(K, -1)], axis=1))
    g, m = grid[nn], mom[nn]                                             # the crossings, by candidate
    D = _finger_directions(mask, corners, r2 + 2, directions, inside=inside)
    if K > 1:
        Dk = D[kk]
        split = (kk == np.arange(K)[:, None]).astype(np.float64)        # (K, M): which crossings are whose
    C = np.zeros((K, 2))                                                 # centres, relative to the pixels
    alive = [True] * K
    radius = [0.0] * K
    reach2 = (r2 + 2.5) ** 2
    for it in range(2):
        if K > 1:
            rel = g - C[kk]
            sel = ((rel * Dk) @ _ONES2 <= 0.0) & ((rel * rel) @ _ONES2 <= reach2)  # the cap
            S = (split * sel) @ m
        elif it == 0:  # centred on the pixel: the grid's own offsets
            sel = (g @ D[0] <= 0.0) & (grid_r2[nn] <= reach2)
            S = (sel @ m)[None]
        else:
            rel = g - C[0]
            sel = (rel @ D[0] <= 0.0) & ((rel * rel) @ _ONES2 <= reach2)
            S = (sel @ m)[None]
        for k, sums in enumerate(S.tolist()):
            if not alive[k]:
                continue
            fit = _kasa(*sums)
            if fit is None or math.hypot(fit[0], fit[1]) > r2 + 1 or fit[2] > 2 * r2 + 2:
                alive[k] = False
                continue
            C[k] = fit[:2]
            radius[k] = fit[2]
    return [(C[k].tolist(), D[k], radius[k]) if alive[k] else None for k in range(K)]


def _kasa(n, su, sv, suu, suv, svv, suuu, suuv, suvv, svvv):
    """The Kåsa circle ``(cx, cy, radius)`` of points given by their sums (as :func:`fit_circle`: on
    the points centred at their mean; None with fewer than 5 points, an ill-conditioned system or no
    positive radius). Plain floats: a handful of candidates is faster so than as arrays."""
    if n < 5:
        return None
    mx, my = su / n, sv / n
    cuu = suu - su * mx                                 # centred second moments
    cuv = suv - su * my
    cvv = svv - sv * my
    det = cuu * cvv - cuv * cuv
    if not det > 1e-12 * max(cuu * cvv, 1e-300):
        return None
    # Σ u'(u'² + v'²) and Σ v'(u'² + v'²) of the centred points u' = u − mx, v' = v − my
    bu = (suuu - 3 * mx * suu + 2 * n * mx ** 3) + (suvv - 2 * my * suv - mx * svv + 2 * n * mx * my * my)
    bv = (svvv - 3 * my * svv + 2 * n * my ** 3) + (suuv - 2 * mx * suv - my * suu + 2 * n * mx * mx * my)
    cx = (cvv * bu - cuv * bv) / det / 2
    cy = (cuu * bv - cuv * bu) / det / 2
    rad2 = (cuu + cvv) / n + cx * cx + cy * cy
    if not (math.isfinite(rad2) and rad2 > 0):
        return None
    return cx + mx, cy + my, math.sqrt(rad2)


_ONES2 = np.ones(2)  # row sums of (N, 2) products by one small matrix product


def _row_sums(a: np.ndarray) -> np.ndarray:
    """``a.sum(axis=1)`` without ndarray.sum's Python layer (a few calls per tracked view)."""
    return np.add.reduce(a, axis=1)


_ANGLES = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
_UNIT = np.column_stack([np.cos(_ANGLES), np.sin(_ANGLES)])


@lru_cache(maxsize=64)
def _circle_offsets(rho: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Integer offsets (dx, dy) of the 64 samples on a circle of radius ``rho`` around a pixel:
    ``rint(p + rho·unit) = p + rint(rho·unit)`` for a whole pixel p unless a sample lies half-way
    between pixels (None then; no radius up to 200 px has one)."""
    x = rho * _UNIT
    if np.any(np.abs(np.abs(x - np.floor(x)) - 0.5) < 1e-6):
        return None
    q = np.rint(x).astype(np.intp)
    return q[:, 0].copy(), q[:, 1].copy()


@lru_cache(maxsize=256)
def _circle_flat(rho: int, width: int) -> np.ndarray:
    """:func:`_circle_offsets` (which must exist) as offsets into a flattened mask ``width`` pixels wide."""
    dx, dy = _circle_offsets(rho)
    return dy * width + dx


def _finger_directions(mask: np.ndarray, corners, rho: int, fallback, *, inside: bool = False) -> np.ndarray:
    """Unit vectors from the whole pixels ``corners`` [(x, y), ...] into the finger: the mean
    direction of the skin samples on a circle of radius ``rho`` around each (``fallback[k]`` where
    none is skin); ``inside``: the caller knows every circle lies within the mask."""
    h, w = mask.shape
    circle = _circle_offsets(rho) if inside else None
    if circle is not None and len(corners) == 1:
        x, y = corners[0]
        skin = (mask.ravel()[_circle_flat(rho, w) + (y * w + x)] > 0)[None]
    elif circle is not None:
        P = np.array(corners, dtype=np.intp)
        skin = mask[P[:, 1:] + circle[1], P[:, :1] + circle[0]] > 0     # (K, 64)
    else:
        q = np.rint(np.array(corners, dtype=np.float64)[:, None, :] + rho * _UNIT).astype(np.intp)  # (K, 64, 2)
        qx, qy = q[..., 0], q[..., 1]
        ok = (qx >= 0) & (qx < w) & (qy >= 0) & (qy < h)
        skin = np.zeros(ok.shape, bool)
        skin[ok] = mask[qy[ok], qx[ok]] > 0
    D = skin @ _UNIT
    for k, (dx, dy) in enumerate(D.tolist()):
        n = math.hypot(dx, dy)
        D[k] = (dx / n, dy / n) if n > 0 else fallback[k]
    return D
