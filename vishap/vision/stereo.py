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

from dataclasses import dataclass

import cv2
import numpy as np

from vishap.vision.rig import StereoRig

__all__ = ["StereoPoint", "StereoConfig", "triangulate_tip", "dense_tip", "DenseMatcher"]


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

    def __bool__(self) -> bool:
        return self.ok


def _disparity_limits(rig: StereoRig, cfg: StereoConfig) -> tuple[float, float]:
    fb = rig.rectified_fx_px * abs(rig.rectified_baseline_m)
    return fb / cfg.max_depth_m, fb / cfg.min_depth_m


def triangulate_tip(rig: StereoRig, uv_left, uv_right, config: StereoConfig = StereoConfig()) -> StereoPoint:
    """Triangulate one tip from raw (distorted) pixels of the left and right image."""
    if uv_left is None or uv_right is None:
        return StereoPoint(False, reason="tip missing in one view")
    rl = rig.rectify_points(np.asarray(uv_left, dtype=np.float64).reshape(1, 2), "left")[0]
    rr = rig.rectify_points(np.asarray(uv_right, dtype=np.float64).reshape(1, 2), "right")[0]
    return triangulate_rectified_tip(rig, rl, rr, config)


def triangulate_rectified_tip(rig: StereoRig, rl, rr, config: StereoConfig = StereoConfig()) -> StereoPoint:
    """As :func:`triangulate_tip`, for pixels already in the rectified images."""
    rl = np.asarray(rl, dtype=np.float64)
    rr = np.asarray(rr, dtype=np.float64)
    epi = float(abs(rl[1] - rr[1]))
    sign = 1.0 if rig.rectified_baseline_m > 0 else -1.0
    disp = float(rl[0] - rr[0])
    dmin, dmax = _disparity_limits(rig, config)
    if not np.isfinite(epi) or epi > config.max_epipolar_px:
        return StereoPoint(False, disparity_px=disp, epipolar_px=epi, reason=f"epipolar error {epi:.2f} px")
    if not (dmin <= sign * disp <= dmax):
        return StereoPoint(False, disparity_px=disp, epipolar_px=epi,
                           reason=f"disparity {disp:.1f} px outside [{dmin:.1f}, {dmax:.1f}]")
    v = 0.5 * (rl[1] + rr[1])
    s = np.array([rl[0], v, disp, 1.0])
    hom = rig.Q @ s
    p_rect = hom[:3] / hom[3]
    # first-order propagation: ds/d(ul, vl, ur, vr)
    J_s = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.5], [1.0, 0.0, -1.0, 0.0]])
    J_p = (rig.Q[:3, :3] - np.outer(p_rect, rig.Q[3, :3])) / hom[3]  # dp/d(u, v, d)
    J = J_p @ J_s
    cov_rect = (config.sigma_px ** 2) * (J @ J.T)
    R1 = rig.R1
    p_cam = R1.T @ p_rect
    cov_cam = R1.T @ cov_rect @ R1
    return StereoPoint(True, p_cam=p_cam, cov_cam=cov_cam, disparity_px=disp, epipolar_px=epi)


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
