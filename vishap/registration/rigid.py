"""Absolute orientation: the rigid transform between two frames from paired points.

Implements the registration step of VisHap §2.2, Eq. 3 (``ᴴP = ᴴ_C R ᶜP + t``): given pairs of
the same points in two frames (end-effector positions triangulated in the camera frame and
computed by forward kinematics in the robot frame), find the rotation and translation that map
one onto the other in the least-squares sense. The closed form is Horn's / Umeyama's
(weighted centroids, SVD of the cross-covariance, determinant correction so the result is always
a proper rotation, never a reflection). Estimators follow scikit-image's ``from_estimate``
convention: a degenerate fit returns a value that tests false and carries ``.reason``.

``RigidTransform.from_estimate_robust`` adds a robust mode for outliers: random minimal samples
(three pairs, batched SVD) scored by least median of squares (no threshold needed) or by an
inlier count (RANSAC, with a threshold in metres), then a weighted refit on the inliers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vishap._core.errors import CalibrationError, ShapeError
from vishap._core.pose import from_rt, invert, is_rotation, rotation_angle

__all__ = ["RigidTransform", "kabsch_umeyama", "degeneracy"]

# Relative size of the second principal extent below which a point set counts as collinear.
_COLLINEAR_RTOL = 1e-6
# Median of a chi-square variable with 3 degrees of freedom (isotropic 3-D Gaussian residuals).
_CHI2_3_MEDIAN = 2.365974
# 99.9 % quantile of chi-square(3): inlier gate on squared residuals / sigma².
_CHI2_3_Q999 = 16.266


def _as_pairs(p_src, p_dst, weights):
    """Shape-check the inputs (shape errors raise; bad values are reported by :func:`degeneracy`)."""
    src = np.asarray(p_src, dtype=np.float64)
    dst = np.asarray(p_dst, dtype=np.float64)
    if src.ndim == 1 and src.size == 3:
        src = src[None]
    if dst.ndim == 1 and dst.size == 3:
        dst = dst[None]
    if src.ndim != 2 or src.shape[1] != 3:
        raise ShapeError(f"p_src: expected shape (N, 3), got {src.shape}")
    if dst.ndim != 2 or dst.shape[1] != 3:
        raise ShapeError(f"p_dst: expected shape (N, 3), got {dst.shape}")
    if src.shape[0] != dst.shape[0]:
        raise ShapeError(f"p_src and p_dst must pair up: {src.shape[0]} vs {dst.shape[0]} points")
    if weights is None:
        w = np.ones(len(src))
    else:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape[0] != src.shape[0]:
            raise ShapeError(f"weights: expected {src.shape[0]} values, got {w.shape[0]}")
    return src, dst, w


def _check_values(src: np.ndarray, dst: np.ndarray, w: np.ndarray) -> str:
    """Reasons that do not need the geometry: non-finite values, bad weights, too few pairs."""
    if not np.isfinite(src).all():
        return f"p_src holds NaN or inf ({int(np.sum(~np.isfinite(src).all(axis=1)))} of {len(src)} points)"
    if not np.isfinite(dst).all():
        return f"p_dst holds NaN or inf ({int(np.sum(~np.isfinite(dst).all(axis=1)))} of {len(dst)} points)"
    if not np.isfinite(w).all() or (w < 0).any():
        return "weights must be finite and non-negative"
    n = int(np.count_nonzero(w))
    if n < 3:
        return f"need at least 3 point pairs with positive weight, got {n}"
    if max(float(np.abs(src).max()), float(np.abs(dst).max())) > 1e150:
        return "coordinates too large to square safely (|p| > 1e150)"
    return ""


def _spread_reason(name: str, p: np.ndarray, centred: np.ndarray, w: np.ndarray) -> str:
    """'' unless the weighted point set is (nearly) a single point or a line.

    From the invariants of the 3×3 scatter C = Σ w q qᵀ (eigenvalues λ1 ≥ λ2 ≥ λ3, the squared
    principal extents): tr C = Σλ and c2 = ½(tr² C − tr C²) = λ1λ2 + λ1λ3 + λ2λ3 ≈ λ1λ2 when the
    set is nearly a line, so c2 / tr² ≈ λ2/λ1 = (second extent / first)².
    """
    C = (centred * w[:, None]).T @ centred
    tr = float(C[0, 0] + C[1, 1] + C[2, 2])
    if tr <= (1e-12 * max(1.0, float(np.abs(p).max()))) ** 2 * float(w.sum()):
        return f"{name}: all points coincide"
    c2 = 0.5 * (tr * tr - float(np.sum(C * C)))
    ratio = math.sqrt(max(c2, 0.0)) / tr
    if ratio <= _COLLINEAR_RTOL:
        return f"{name}: points are collinear (second extent {ratio:.1e} of the first)"
    return ""


def _fit(src: np.ndarray, dst: np.ndarray, w: np.ndarray):
    """Checked weighted fit: ``(R, t, '')`` or ``(None, None, reason)``."""
    why = _check_values(src, dst, w)
    if why:
        return None, None, why
    if not (w > 0).all():
        keep = w > 0
        src, dst, w = src[keep], dst[keep], w[keep]
    wsum = float(w.sum())
    mu_s = (w @ src) / wsum
    mu_d = (w @ dst) / wsum
    a = src - mu_s
    b = dst - mu_d
    why = _spread_reason("p_src", src, a, w) or _spread_reason("p_dst", dst, b, w)
    if why:
        return None, None, why
    H = (a * w[:, None]).T @ b  # Σ w a bᵀ
    U, _, Vt = np.linalg.svd(H)
    V = Vt.T
    M = V @ U.T
    det = (M[0, 0] * (M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]) - M[0, 1] * (M[1, 0] * M[2, 2] - M[1, 2] * M[2, 0])
           + M[0, 2] * (M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]))
    d = 1.0 if det >= 0 else -1.0  # never a reflection
    R = (V * np.array([1.0, 1.0, d])) @ U.T
    t = mu_d - R @ mu_s
    if not (np.isfinite(R).all() and np.isfinite(t).all()):
        return None, None, "numerical failure in the SVD"
    return R, t, ""


def _best_transform(src, dst, score_on, r2, gate2):
    """Least-squares transform on the scored pairs that the best hypothesis calls inliers."""
    keep = score_on[r2 <= gate2]
    R, t, why = _fit(src[keep], dst[keep], np.ones(len(keep)))
    if why:  # fall back to the three best-fitting pairs
        keep = score_on[np.argsort(r2)[:3]]
        R, t = kabsch_umeyama(src[keep], dst[keep], np.ones(3))
    return R, t


def degeneracy(p_src, p_dst, weights=None) -> str:
    """Why these pairs cannot determine a rigid transform ('' when they can)."""
    return _fit(*_as_pairs(p_src, p_dst, weights))[2]


def kabsch_umeyama(p_src: np.ndarray, p_dst: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares rotation and translation, ``p_dst ≈ R p_src + t`` (no checks).

    Works on a batch too: ``p_src``/``p_dst`` of shape (..., N, 3), ``w`` (..., N).
    """
    wsum = np.sum(w, axis=-1, keepdims=True)
    mu_s = (w[..., None, :] @ p_src)[..., 0, :] / wsum
    mu_d = (w[..., None, :] @ p_dst)[..., 0, :] / wsum
    a = p_src - mu_s[..., None, :]
    b = p_dst - mu_d[..., None, :]
    H = np.swapaxes(a * w[..., None], -1, -2) @ b  # Σ w a bᵀ
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, -1, -2)
    d = np.sign(np.linalg.det(V @ np.swapaxes(U, -1, -2)))
    d = np.where(d == 0, 1.0, d)
    V = V * np.stack([np.ones_like(d), np.ones_like(d), d], axis=-1)[..., None, :]
    R = V @ np.swapaxes(U, -1, -2)
    t = mu_d - (R @ mu_s[..., None])[..., 0]
    return R, t


@dataclass(frozen=True, eq=False)
class RigidTransform:
    """A rigid transform ``p_dst = R p_src + t`` (e.g. ``T_robot_cam``: src = cam, dst = robot).

    Built by :meth:`from_estimate` / :meth:`from_estimate_robust` (which keep the point pairs so
    that :meth:`residuals` and :meth:`error_report` describe the fit) or :meth:`from_matrix`.
    A failed estimate tests false, says why in ``reason`` and refuses to be applied.
    """

    R: np.ndarray
    t: np.ndarray
    reason: str = ""
    p_src: np.ndarray | None = field(default=None, repr=False)
    p_dst: np.ndarray | None = field(default=None, repr=False)
    inliers: np.ndarray | None = field(default=None, repr=False)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def failed(cls, reason: str, p_src=None, p_dst=None) -> "RigidTransform":
        nan = np.full((3, 3), np.nan)
        return cls(R=nan, t=np.full(3, np.nan), reason=reason, p_src=p_src, p_dst=p_dst)

    @classmethod
    def identity(cls) -> "RigidTransform":
        return cls(R=np.eye(3), t=np.zeros(3))

    @classmethod
    def from_matrix(cls, T) -> "RigidTransform":
        """Wrap a 4×4 homogeneous transform (checked: last row, proper rotation)."""
        T = np.asarray(T, dtype=np.float64)
        if T.shape != (4, 4):
            raise ShapeError(f"T: expected shape (4, 4), got {T.shape}")
        if not np.all(np.isfinite(T)) or not np.allclose(T[3], [0, 0, 0, 1]) or not is_rotation(T[:3, :3]):
            raise ShapeError("T: not a rigid transform (finite, last row [0 0 0 1], proper rotation)")
        return cls(R=T[:3, :3].copy(), t=T[:3, 3].copy())

    @classmethod
    def from_estimate(cls, p_src, p_dst, weights=None) -> "RigidTransform":
        """Closed-form least-squares fit of ``p_dst ≈ R p_src + t`` over (N, 3) point pairs.

        ``weights`` (N,) ≥ 0 scale each pair's squared error (e.g. inverse variances). Returns a
        falsy estimate with ``reason`` for fewer than 3 weighted pairs, coincident or collinear
        points, NaN/inf or bad weights.
        """
        src, dst, w = _as_pairs(p_src, p_dst, weights)
        R, t, why = _fit(src, dst, w)
        if why:
            return cls.failed(why, src, dst)
        return cls(R=R, t=t, p_src=src, p_dst=dst, inliers=w > 0)

    @classmethod
    def from_estimate_robust(
        cls,
        p_src,
        p_dst,
        weights=None,
        *,
        threshold: float | None = None,
        max_trials: int = 1000,
        seed: int | np.random.Generator = 0,
        refine: int = 3,
    ) -> "RigidTransform":
        """Fit in the presence of outliers; ``inliers`` marks the pairs kept.

        With ``threshold`` (metres) this is RANSAC (MSAC scoring: truncated squared residuals) on
        minimal 3-pair hypotheses. Without it, least median of squares (tolerates up to
        half outliers) picks the hypothesis and the noise level σ is estimated from the median
        residual; pairs within the 99.9 % gate of a 3-D Gaussian (≈ 4σ) are inliers. Either way
        the result is refitted on the inliers (``refine`` rounds, weights applied). Hypotheses are
        drawn in batches until the inlier share seen so far gives 99.9 % confidence of one clean
        sample (at most ``max_trials``) and are scored on at most 1000 pairs.
        """
        src, dst, w = _as_pairs(p_src, p_dst, weights)
        why = _fit(src, dst, w)[2]
        if why:
            return cls.failed(why, src, dst)
        if threshold is not None and not (threshold > 0 and math.isfinite(threshold)):
            raise ShapeError(f"threshold: expected a positive distance in metres, got {threshold}")
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        cand = np.flatnonzero(w > 0)
        n = len(cand)
        # hypotheses are scored on at most 1000 pairs (the refit below uses all of them)
        score_on = cand if n <= 1000 else rng.choice(cand, 1000, replace=False)
        s_src, s_dst = src[score_on], dst[score_on]
        best_score, best_r2 = math.inf, None
        done, needed, chunk = 0, int(max_trials), 64
        while done < needed:
            if n > 3:
                draw = rng.integers(0, n, size=(2 * chunk, 3))
                distinct = (draw[:, 0] != draw[:, 1]) & (draw[:, 0] != draw[:, 2]) & (draw[:, 1] != draw[:, 2])
                idx = cand[draw[distinct][:chunk]]
            else:
                idx = cand[None]
            done += chunk
            # skip near-collinear samples (their rotation about the line is arbitrary)
            e1 = src[idx[:, 1]] - src[idx[:, 0]]
            e2 = src[idx[:, 2]] - src[idx[:, 0]]
            cx = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
            cy = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
            cz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
            area2 = cx * cx + cy * cy + cz * cz
            idx = idx[area2 > 1e-12 * np.maximum(np.sum(e1 * e1, axis=1), np.sum(e2 * e2, axis=1)) ** 2]
            if len(idx) == 0:
                if n == 3:
                    break
                continue
            Rs, ts = kabsch_umeyama(src[idx], dst[idx], np.ones(idx.shape))
            r2 = np.sum((s_src @ np.swapaxes(Rs, -1, -2) + ts[:, None, :] - s_dst) ** 2, axis=-1)
            # least median of squares, or MSAC (truncated squares) with a threshold
            scores = np.median(r2, axis=1) if threshold is None else np.minimum(r2, threshold**2).sum(axis=1)
            k = int(np.argmin(scores))
            if scores[k] < best_score:
                best_score, best_r2 = float(scores[k]), r2[k]
                if threshold is None:
                    gate2 = _CHI2_3_Q999 * max(float(np.median(best_r2)) / _CHI2_3_MEDIAN, 1e-300)
                else:
                    gate2 = threshold**2
                eps = float(np.mean(best_r2 <= gate2))  # inlier share: adaptive number of trials
                if eps >= 1.0:
                    needed = min(needed, done)
                elif eps > 0:
                    needed = min(int(max_trials), max(chunk, math.ceil(math.log(1e-3) / math.log1p(-(eps**3)))))
            if n == 3:
                break
        if best_r2 is None:
            return cls.failed("every random sample of 3 pairs was collinear", src, dst)
        if threshold is None:
            sigma2 = float(np.median(best_r2)) / _CHI2_3_MEDIAN
            sigma2 *= (1.0 + 5.0 / max(len(score_on) - 3, 1)) ** 2  # Rousseeuw's small-sample factor
            gate2 = _CHI2_3_Q999 * max(sigma2, 1e-300)
        else:
            gate2 = threshold**2
        # inliers of the best hypothesis on all pairs: refit the best sample's transform
        R, t = _best_transform(src, dst, score_on, best_r2, gate2)
        inl = (np.sum((src @ R.T + t - dst) ** 2, axis=1) <= gate2) & (w > 0)
        fit = None
        for _ in range(max(1, refine)):
            R, t, why = _fit(src[inl], dst[inl], w[inl])
            if why:
                break
            fit = (R, t)
            res2 = np.sum((src @ R.T + t - dst) ** 2, axis=1)
            if threshold is None:
                gate2 = _CHI2_3_Q999 * max(float(np.median(res2[inl])) / _CHI2_3_MEDIAN, 1e-300)
            new = (res2 <= gate2) & (w > 0)
            if np.array_equal(new, inl):
                break
            inl = new
        if fit is None:
            return cls.failed("no consensus: fewer than 3 non-collinear inliers", src, dst)
        R, t = fit
        return cls(R=R, t=t, p_src=src, p_dst=dst, inliers=inl)

    # ------------------------------------------------------------------ use
    def __bool__(self) -> bool:
        return not self.reason

    def _check(self) -> None:
        if self.reason:
            raise CalibrationError(f"rigid transform estimate failed: {self.reason}")

    @property
    def T(self) -> np.ndarray:
        """The 4×4 homogeneous matrix."""
        self._check()
        return from_rt(self.R, self.t)

    def apply(self, p) -> np.ndarray:
        """Map points (3,) or (N, 3) from the source into the destination frame."""
        self._check()
        p = np.asarray(p, dtype=np.float64)
        return p @ self.R.T + self.t

    def inverse(self) -> "RigidTransform":
        """The transform from the destination back to the source frame (pairs swapped)."""
        self._check()
        Ti = invert(self.T)
        return RigidTransform(R=Ti[:3, :3], t=Ti[:3, 3], p_src=self.p_dst, p_dst=self.p_src, inliers=self.inliers)

    def __matmul__(self, other: "RigidTransform") -> "RigidTransform":
        return RigidTransform.from_matrix(self.T @ other.T)

    def residual_vectors(self, p_src=None, p_dst=None) -> np.ndarray:
        """``R p_src + t − p_dst`` per pair (N, 3); defaults to the pairs it was fitted on."""
        src = self.p_src if p_src is None else np.asarray(p_src, dtype=np.float64)
        dst = self.p_dst if p_dst is None else np.asarray(p_dst, dtype=np.float64)
        if src is None or dst is None:
            raise ShapeError("residuals: no point pairs stored; pass p_src and p_dst")
        return self.apply(src) - dst

    def residuals(self, p_src=None, p_dst=None) -> np.ndarray:
        """Euclidean distance (metres) between ``R p_src + t`` and ``p_dst`` for each pair (N,)."""
        return np.linalg.norm(self.residual_vectors(p_src, p_dst), axis=1)

    def error_report(self, p_src=None, p_dst=None, *, inliers_only: bool = True) -> dict:
        """Per-axis error in the destination frame (VisHap quotes the mean per dimension), mm."""
        e = self.residual_vectors(p_src, p_dst)
        if inliers_only and p_src is None and self.inliers is not None:
            e = e[self.inliers]
        e_mm = e * 1e3
        return {
            "pairs": int(len(e_mm)),
            "per_axis_error_mm": np.mean(np.abs(e_mm), axis=0).tolist(),
            "per_axis_rms_mm": np.sqrt(np.mean(e_mm**2, axis=0)).tolist(),
            "rms_mm": float(np.sqrt(np.mean(np.sum(e_mm**2, axis=1)))),
            "max_mm": float(np.max(np.linalg.norm(e_mm, axis=1))),
        }

    def compare(self, T_true) -> dict:
        """Rotation (degrees) and translation (mm) error against a reference transform."""
        T_true = np.asarray(T_true, dtype=np.float64)
        return {
            "rotation_error_deg": math.degrees(rotation_angle(self.R, T_true[:3, :3])),
            "translation_error_mm": float(np.linalg.norm(self.t - T_true[:3, 3]) * 1e3),
        }
