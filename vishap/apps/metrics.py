"""Figures of a demo run computed from its logged signals (issue 9 part 2; VisHap §3, Fig. 6).

All functions take plain arrays so that the same figures come out of a live run, a batch run and
a replay. Conventions: ``depth`` is positive below the object's surface (m); the Fig. 6 abscissa,
the fingertip's *distance* to the surface, is ``-depth``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "tip3d_errors_mm",
    "rising_edges",
    "Approach",
    "approaches",
    "linear_fit",
    "force_depth_r2",
]


def tip3d_errors_mm(p_est: np.ndarray, p_true: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Euclidean errors (mm) of the estimates on the rows where ``valid`` (and both are finite)."""
    p_est = np.asarray(p_est, dtype=float).reshape(-1, 3)
    p_true = np.asarray(p_true, dtype=float).reshape(-1, 3)
    ok = np.asarray(valid, bool) & np.all(np.isfinite(p_est), 1) & np.all(np.isfinite(p_true), 1)
    return 1e3 * np.linalg.norm(p_est[ok] - p_true[ok], axis=1)


def rising_edges(flag: np.ndarray, *, min_gap: int = 1) -> np.ndarray:
    """Indices where ``flag`` turns true, ignoring re-triggers within ``min_gap`` samples of a fall."""
    f = np.asarray(flag, bool)
    if f.size == 0:
        return np.zeros(0, int)
    idx = np.flatnonzero(f & ~np.concatenate([[False], f[:-1]]))
    if min_gap <= 1 or idx.size == 0:
        return idx
    falls = np.flatnonzero(~f & np.concatenate([[False], f[:-1]]))
    keep = [idx[0]]
    for i in idx[1:]:
        last_fall = falls[falls < i]
        if last_fall.size and i - last_fall[-1] < min_gap:
            continue
        keep.append(i)
    return np.asarray(keep, int)


@dataclass(frozen=True)
class Approach:
    """One approach of the finger to the object's surface.

    ``t_touch``: when the finger pad reached the surface (ground truth of the scripted finger);
    ``p_touch``: where (robot frame); ``lead_time_s``: how long before ``t_touch`` the device was
    in place (within ``tol``) and stayed there — negative when it arrived late, ``None`` when it
    never arrived within the window; ``position_error_m``: device contact point to ``p_touch`` at
    ``t_touch``.
    """

    t_touch: float
    p_touch: np.ndarray
    lead_time_s: float | None
    position_error_m: float


def approaches(
    t: np.ndarray,
    finger_depth: np.ndarray,
    finger_point: np.ndarray,
    device_point: np.ndarray,
    *,
    tol_m: float = 0.002,
    min_gap_s: float = 0.15,
    late_window_s: float = 0.3,
) -> list[Approach]:
    """Find approaches (finger pad crossing the surface height) and rate the device at each.

    ``finger_depth`` is the scripted finger's depth below the surface (m, servo rate), so the
    crossings come from ground truth, never from the device; ``finger_point`` the pad point
    projected on the surface; ``device_point`` the device's contact point (top of its passive
    object), both (N, 3) robot frame.
    """
    t = np.asarray(t, float)
    if t.size < 2:
        return []
    dt = float(np.median(np.diff(t)))
    touching = np.asarray(finger_depth, float) >= 0.0
    edges = rising_edges(touching, min_gap=max(1, int(round(min_gap_s / dt))))
    out = []
    dev = np.asarray(device_point, float)
    fin = np.asarray(finger_point, float)
    for k, i in enumerate(edges):
        p_touch = fin[i]
        dist = np.linalg.norm(dev - p_touch, axis=1)
        start = 0 if k == 0 else edges[k - 1]
        # in place before the touch: the last stretch ending at i where dist <= tol
        lead = None
        if dist[i] <= tol_m:
            j = i
            while j > start and dist[j - 1] <= tol_m:
                j -= 1
            lead = float(t[i] - t[j])
        else:
            stop = min(len(t), i + int(round(late_window_s / dt)) + 1)
            after = np.flatnonzero(dist[i:stop] <= tol_m)
            if after.size:
                lead = -float(t[i + after[0]] - t[i])
        out.append(Approach(float(t[i]), p_touch.copy(), lead, float(dist[i])))
    return out


def linear_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares line ``y = a x + b`` → ``(a, b, r2)``; NaNs when fewer than 3 points or x constant."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 3 or np.ptp(x) == 0.0:
        return float("nan"), float("nan"), float("nan")
    a, b = np.polyfit(x, y, 1)
    ss_res = float(np.sum((y - (a * x + b)) ** 2))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else float("nan")
    return float(a), float(b), r2


def force_depth_r2(depth: np.ndarray, force_n: np.ndarray, *, min_depth_m: float = 1e-4) -> tuple[float, float, float]:
    """Fig. 6 linearity: fit normal force against depth over the samples pressed ≥ ``min_depth_m``."""
    depth = np.asarray(depth, float)
    sel = depth >= min_depth_m
    return linear_fit(depth[sel], np.asarray(force_n, float)[sel])
