"""The stereo rig: two calibrated cameras, their rectification, projection and triangulation.

Frames and conventions (OpenCV): the rig frame is the **left camera frame** (``p_cam``: x right,
y down, z forward, metres). The right camera sees ``p_right = R @ p_cam + T``; the baseline is
``|T|``. Pixels are float ``(u, v)`` with the centre of the top-left pixel at (0, 0).
Distortion follows OpenCV's model (k1, k2, p1, p2[, k3[, k4, k5, k6]]).

Files are OpenCV FileStorage YAML (what ``cv2.FileStorage`` writes) with the nodes
``image_size`` (``[width, height]``; also written as OpenCV's ``image_width``, ``image_height``), ``K1``,
``D1``, ``K2``, ``D2``, ``R``, ``T`` and the rectification ``R1``, ``R2``, ``P1``, ``P2``, ``Q``
(all required in a file; the constructor computes the rectification with ``cv2.stereoRectify``
when it is not given), and optionally what the calibration was made from and how well it fits:
``rms_px`` (the stereo RMS reprojection error, pixels), ``board`` (the target's kind, e.g.
``chessboard``), ``board_width``, ``board_height`` (its pattern size: inner corners of a chessboard,
squares of a ChArUco board) and ``square_size`` (metres) — the last three under the names OpenCV's
calibration sample writes. ``vishap calibrate stereo`` writes them all. The names OpenCV's stereo
sample (``stereo_calib.cpp``) writes, ``M1``/``M2`` for ``K1``/``K2``, are read as well, also from
its two files (``intrinsics.yml``: M1 D1 M2 D2; ``extrinsics.yml``: R T R1 R2 P1 P2 Q)
concatenated; the sample writes no image size, so such a file needs an ``image_size`` line. Files are parsed by
:mod:`vishap._core.filestorage`, never by cv2's reader, and every value is checked for range and
consistency (rotations, ``R2·R = R1``, ``Q`` agreeing with ``P1``/``P2``) before use.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from vishap._core.check import as_array, as_points
from vishap._core.config import write_atomic
from vishap._core.filestorage import read_filestorage
from vishap._core.errors import ConfigError, VishapError
from vishap._core.pose import is_rotation

__all__ = ["StereoRig"]

_DIST_LENGTHS = (4, 5, 8, 12, 14)
_RECT_FIELDS = {"R1": (3, 3), "R2": (3, 3), "P1": (3, 4), "P2": (3, 4), "Q": (4, 4)}
#: File nodes: ours first, then the names OpenCV's stereo_calib sample writes.
_MATRIX_NODES = {"K1": ("K1", "M1"), "D1": ("D1",), "K2": ("K2", "M2"), "D2": ("D2",), "R": ("R",), "T": ("T",)}
_OTHER_NODES = {"image_size", "image_width", "image_height", "rms_px", "board", "board_width", "board_height",
                "square_size"}
_MAX_BOARD_SIDE = 1000  # corners or squares along one side of a calibration target
_SQUARE_RANGE_M = (1e-4, 1.0)
_MAX_IMAGE_SIDE = 100_000  # pixels
_FOCAL_RANGE = (0.01, 1000.0)  # focal length / longer image side: fields of view of 179.4° … 0.06°
_MAX_DISTORTION = 1e4  # |coefficient|; real rational models stay below a few hundred
_BASELINE_RANGE_M = (1e-4, 10.0)
_ROT_TOL = 1e-6


def _distort_project(p: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pinhole + OpenCV radial/tangential distortion, vectorised; ``p`` (N, 3) in that camera's frame."""
    z = p[:, 2]
    x = p[:, 0] / z
    y = p[:, 1] / z
    d = np.zeros(8)
    d[: min(8, dist.size)] = dist[:8]
    k1, k2, p1, p2, k3, k4, k5, k6 = d
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    u = K[0, 0] * xd + K[0, 1] * yd + K[0, 2]
    v = K[1, 1] * yd + K[1, 2]
    return np.stack([u, v], axis=1)


@dataclass(eq=False)
class StereoRig:
    """Two calibrated cameras. All arrays are float64; see the module docstring for conventions.

    Attributes
    ----------
    image_size: (width, height) in pixels, the same for both cameras.
    K_left, K_right: 3×3 intrinsic matrices (pixels).
    dist_left, dist_right: OpenCV distortion coefficients (4, 5, 8, 12 or 14 values).
    R, T: pose of the right camera: ``p_right = R @ p_left + T`` (T in metres).
    R1, R2, P1, P2, Q: rectification (``cv2.stereoRectify``); computed when not given.
    """

    image_size: tuple[int, int]
    K_left: np.ndarray
    dist_left: np.ndarray
    K_right: np.ndarray
    dist_right: np.ndarray
    R: np.ndarray
    T: np.ndarray
    R1: np.ndarray | None = None
    R2: np.ndarray | None = None
    P1: np.ndarray | None = None
    P2: np.ndarray | None = None
    Q: np.ndarray | None = None
    rms_px: float | None = None
    board: str | None = None
    board_size: tuple[int, int] | None = None   # (width, height): inner corners / squares
    square_m: float | None = None
    _cache: dict = field(default_factory=dict, init=False, repr=False)  # what the fields give (see rectified_view)

    def __setattr__(self, name: str, value) -> None:
        # what is derived from the fields (rectification maps, each view's constants) is kept until a
        # field is assigned: a rig is changed by assigning its fields, never by writing into their arrays
        object.__setattr__(self, name, value)
        if not name.startswith("_"):
            object.__setattr__(self, "_cache", {})

    def __post_init__(self) -> None:
        try:
            w, h = (int(s) for s in self.image_size)
        except (TypeError, ValueError, OverflowError):
            raise ConfigError(f"expected (width, height), got {self.image_size!r}", field="image_size") from None
        if not (0 < w <= _MAX_IMAGE_SIDE and 0 < h <= _MAX_IMAGE_SIDE):
            raise ConfigError(f"image size must be in 1..{_MAX_IMAGE_SIDE} pixels, got {self.image_size}",
                              field="image_size")
        self.image_size = (w, h)
        self.K_left = _check_K(self.K_left, "K1", self.image_size)
        self.K_right = _check_K(self.K_right, "K2", self.image_size)
        self.dist_left = _check_dist(self.dist_left, "D1")
        self.dist_right = _check_dist(self.dist_right, "D2")
        self.R = _check_rotation(self.R, "R")
        self.T = _as_field(lambda: as_array(np.asarray(self.T, dtype=np.float64).reshape(-1), (3,), "T"), "T")
        b = float(np.linalg.norm(self.T))
        if not (_BASELINE_RANGE_M[0] <= b <= _BASELINE_RANGE_M[1]):
            raise ConfigError(f"baseline |T| = {b:.6g} m, expected {_BASELINE_RANGE_M[0]}..{_BASELINE_RANGE_M[1]} m "
                              "(T is in metres)" if b > 0 else "baseline is zero", field="T")
        if self.rms_px is not None:
            self.rms_px = float(self.rms_px)
            if not (math.isfinite(self.rms_px) and 0.0 <= self.rms_px < 1e3):
                raise ConfigError(f"expected a reprojection error in [0, 1000) pixels, got {self.rms_px}",
                                  field="rms_px")
        if self.board is not None and not isinstance(self.board, str):
            raise ConfigError(f"expected text such as 'chessboard', got {self.board!r}", field="board")
        if self.board_size is not None:
            size = tuple(self.board_size) if isinstance(self.board_size, (tuple, list)) else ()
            if len(size) != 2:
                raise ConfigError(f"expected (width, height), got {self.board_size!r}", field="board_width")
            for name, v in zip(("board_width", "board_height"), size):
                if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 2 <= v <= _MAX_BOARD_SIDE:
                    raise ConfigError(f"expected a whole number in 2..{_MAX_BOARD_SIDE}, got {v!r}", field=name)
            self.board_size = (int(size[0]), int(size[1]))
        if self.square_m is not None:
            self.square_m = float(self.square_m)
            if not (math.isfinite(self.square_m) and _SQUARE_RANGE_M[0] <= self.square_m <= _SQUARE_RANGE_M[1]):
                raise ConfigError(f"expected a square side of {_SQUARE_RANGE_M[0]}..{_SQUARE_RANGE_M[1]} m, "
                                  f"got {self.square_m}", field="square_size")
        given = [getattr(self, k) is not None for k in _RECT_FIELDS]
        if any(given) and not all(given):
            missing = [k for k, g in zip(_RECT_FIELDS, given) if not g]
            raise ConfigError(f"rectification is partial: missing {missing}", field=missing[0])
        if all(given):
            for k, shape in _RECT_FIELDS.items():
                setattr(self, k, _as_field(lambda: as_array(getattr(self, k), shape, k), k))
            self._check_rectification()
        else:
            self._rectify()

    def _check_rectification(self) -> None:
        """A given rectification must be the one of these cameras: ``R1``, ``R2`` proper rotations
        with ``R2·R = R1``, ``P1``/``P2`` horizontal rectified projections, ``Q`` built from them."""
        _check_rotation(self.R1, "R1")
        _check_rotation(self.R2, "R2")
        if not np.allclose(self.R2 @ self.R, self.R1, atol=1e-5):
            raise ConfigError("R1 and R2 do not rectify this rig (R2·R must equal R1)", field="R1")
        for name in ("P1", "P2"):
            P = getattr(self, name)
            f = P[0, 0]
            lo, hi = (r * max(self.image_size) for r in _FOCAL_RANGE)
            if not (lo <= f <= hi) or not np.isclose(P[1, 1], f, rtol=1e-9) or P[0, 1] != 0 or P[1, 0] != 0 \
                    or not np.array_equal(P[2], [0.0, 0.0, 1.0, 0.0]):
                raise ConfigError("not a rectified projection [[f 0 cx tx] [0 f cy 0] [0 0 1 0]] with a plausible f",
                                  field=name)
        if np.any(self.P1[:, 3] != 0) or self.P2[1, 3] != 0 or self.P2[0, 3] == 0:
            raise ConfigError("expected a horizontal rectification: P1 without translation, P2 with tx only",
                              field="P2")
        f, cx1, cy1 = self.P1[0, 0], self.P1[0, 2], self.P1[1, 2]
        tx = self.P2[0, 3] / self.P2[0, 0]
        if not np.allclose(self.P2[:2, :3], self.P1[:2, :3] + [[0, 0, self.P2[0, 2] - cx1], [0, 0, 0]], rtol=1e-9):
            raise ConfigError("P1 and P2 differ in focal length or row centre", field="P2")
        Q = np.array([[1.0, 0.0, 0.0, -cx1], [0.0, 1.0, 0.0, -cy1], [0.0, 0.0, 0.0, f],
                      [0.0, 0.0, -1.0 / tx, (cx1 - self.P2[0, 2]) / tx]])
        if not np.allclose(self.Q, Q, rtol=1e-6, atol=1e-9):
            raise ConfigError("does not agree with P1 and P2 (expected cv2.stereoRectify's Q)", field="Q")

    def with_calibration_info(self, *, rms_px: float | None = None, board: str | None = None,
                              board_size: tuple[int, int] | None = None, square_m: float | None = None) -> "StereoRig":
        """A copy that also records the calibration's RMS reprojection error and its board (kind,
        pattern size, square side)."""
        return StereoRig(self.image_size, self.K_left, self.dist_left, self.K_right, self.dist_right, self.R, self.T,
                         self.R1, self.R2, self.P1, self.P2, self.Q, rms_px=rms_px, board=board, board_size=board_size,
                         square_m=square_m)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_fov(
        cls,
        width: int = 640,
        height: int = 480,
        hfov_deg: float = 60.0,
        baseline_m: float = 0.06,
    ) -> "StereoRig":
        """An ideal parallel rig: square pixels, centred principal point, no distortion."""
        if not (0.0 < hfov_deg < 180.0):
            raise ConfigError(f"horizontal field of view must be in (0, 180) degrees, got {hfov_deg}", field="hfov_deg")
        if baseline_m <= 0:
            raise ConfigError(f"baseline must be positive, got {baseline_m}", field="baseline_m")
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
        return cls(
            image_size=(width, height),
            K_left=K.copy(),
            dist_left=np.zeros(5),
            K_right=K.copy(),
            dist_right=np.zeros(5),
            R=np.eye(3),
            T=np.array([-baseline_m, 0.0, 0.0]),
        )

    def _rectify(self) -> None:
        R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(
            self.K_left, self.dist_left, self.K_right, self.dist_right, self.image_size,
            self.R, self.T.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY, alpha=0,
        )
        self.R1, self.R2, self.P1, self.P2, self.Q = R1, R2, P1, P2, Q

    # ------------------------------------------------------------------ properties
    @property
    def width(self) -> int:
        return self.image_size[0]

    @property
    def height(self) -> int:
        return self.image_size[1]

    @property
    def baseline_m(self) -> float:
        """Distance between the optical centres (metres)."""
        return float(np.linalg.norm(self.T))

    @property
    def fx_px(self) -> float:
        """Focal length of the left camera in pixels."""
        return float(self.K_left[0, 0])

    @property
    def hfov_deg(self) -> float:
        """Horizontal field of view of the left camera (degrees)."""
        return math.degrees(2.0 * math.atan2(self.width / 2.0, self.fx_px))

    @property
    def rectified_fx_px(self) -> float:
        return self._derived("rectified_fx_px", lambda: float(self.P1[0, 0]))

    @property
    def rectified_baseline_m(self) -> float:
        """Baseline along the rectified x axis: ``-P2[0, 3] / P2[0, 0]``."""
        return self._derived("rectified_baseline_m", lambda: float(-self.P2[0, 3] / self.P2[0, 0]))

    @property
    def Q_rows(self) -> tuple[tuple[float, float, float, float], ...]:
        """The rows of ``Q`` as floats (for arithmetic on one point at a time)."""
        return self._derived("Q_rows", lambda: tuple(map(tuple, self.Q.tolist())))

    def _derived(self, key: str, make):
        """A value computed from the fields, kept until a field is assigned."""
        try:
            return self._cache[key]
        except KeyError:
            value = self._cache[key] = make()
            return value

    # ------------------------------------------------------------------ geometry
    def project(self, p_cam) -> tuple[np.ndarray, np.ndarray]:
        """Project 3-D points (left-camera frame, metres) into both images.

        Returns ``(uv_left, uv_right)``, each (N, 2) pixels. Points at or behind a camera's
        centre give NaN for that camera.
        """
        p = as_points(p_cam, "p_cam", finite=False)
        p_right = p @ self.R.T + self.T
        uv_l = _distort_project(p, self.K_left, self.dist_left)
        uv_r = _distort_project(p_right, self.K_right, self.dist_right)
        uv_l[p[:, 2] <= 0] = np.nan
        uv_r[p_right[:, 2] <= 0] = np.nan
        return uv_l, uv_r

    def undistort_normalized(self, uv, side: str = "left") -> np.ndarray:
        """Pixels to normalised, undistorted image coordinates (x/z, y/z) of one camera."""
        K, d = (self.K_left, self.dist_left) if side == "left" else (self.K_right, self.dist_right)
        uv = as_points(uv, f"uv_{side}", dim=2)
        if not np.any(d):
            return np.stack([(uv[:, 0] - K[0, 2] - K[0, 1] * (uv[:, 1] - K[1, 2]) / K[1, 1]) / K[0, 0],
                             (uv[:, 1] - K[1, 2]) / K[1, 1]], axis=1)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-14)
        out = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, d, None, None, None, crit)
        return out.reshape(-1, 2)

    def triangulate(self, uv_left, uv_right, *, iterations: int = 4) -> np.ndarray:
        """Triangulate matched pixels (raw, distorted images) to ``p_cam`` (N, 3), metres.

        Midpoint of the two back-projected rays, then Gauss–Newton on the reprojection error in
        both images (exact for noise-free correspondences, the maximum-likelihood point under
        isotropic pixel noise otherwise).
        """
        uv_l = as_points(uv_left, "uv_left", dim=2)
        uv_r = as_points(uv_right, "uv_right", dim=2)
        if uv_l.shape != uv_r.shape:
            raise ConfigError(f"uv_left {uv_l.shape} and uv_right {uv_r.shape} differ in shape", field="uv_right")
        xl = self.undistort_normalized(uv_l, "left")
        xr = self.undistort_normalized(uv_r, "right")
        # Rays in the left frame: p = s*dl (left centre 0), p = c_r + t*dr
        dl = np.column_stack([xl, np.ones(len(xl))])
        dr = np.column_stack([xr, np.ones(len(xr))]) @ self.R  # R^T applied to row vectors
        c_r = -self.R.T @ self.T
        # closest points of two lines
        a = np.einsum("ij,ij->i", dl, dl)
        b = np.einsum("ij,ij->i", dl, dr)
        c = np.einsum("ij,ij->i", dr, dr)
        w0 = -c_r  # origin_l - origin_r
        d_ = dl @ w0
        e_ = dr @ w0
        den = a * c - b * b
        den = np.where(np.abs(den) < 1e-18, 1e-18, den)
        s = (b * e_ - c * d_) / den
        t = (a * e_ - b * d_) / den
        p = 0.5 * (dl * s[:, None] + (c_r + dr * t[:, None]))
        target = np.hstack([uv_l, uv_r])
        h = 1e-7
        for _ in range(iterations):
            r = np.hstack(self.project(p)) - target  # (N, 4)
            J = np.empty((len(p), 4, 3))
            for k in range(3):
                dp = np.zeros(3)
                dp[k] = h
                J[:, :, k] = (np.hstack(self.project(p + dp)) - np.hstack(self.project(p - dp))) / (2 * h)
            JtJ = np.einsum("nik,nil->nkl", J, J)
            Jtr = np.einsum("nik,ni->nk", J, r)
            step = np.linalg.solve(JtJ + 1e-30 * np.eye(3), Jtr[..., None])[..., 0]
            p = p - step
            if np.max(np.abs(step)) < 1e-13:
                break
        return p

    # ------------------------------------------------------------------ rectification
    def rectify_points(self, uv, side: str = "left") -> np.ndarray:
        """Raw pixels of one camera to pixels of its rectified image (N, 2)."""
        return self.rectify_points_fast(as_points(uv, f"uv_{side}", dim=2), side)

    def rectify_points_fast(self, uv: np.ndarray, side: str) -> np.ndarray:
        """:meth:`rectify_points` of an (N, 2) float64 array already checked finite (the pipeline's
        own pixels, a few calls per stereo pair): the same floats without the checks."""
        v = self.rectified_view(side)
        if v.undistorted:
            if len(uv) <= _FEW_POINTS:  # cv2.undistortPoints' arithmetic in floats costs less than its call
                return np.array([v.rectify(a, b) for a, b in uv.tolist()]).reshape(-1, 2)
            # no lens distortion: the same floats without 50 identity iterations per point
            return cv2.undistortPoints(uv.reshape(-1, 1, 2), v.K, None, None, v.R_rect, v.P).reshape(-1, 2)
        return cv2.undistortPoints(uv.reshape(-1, 1, 2), v.K, v.dist, None, v.R_rect, v.P,
                                   _UNDISTORT_CRIT).reshape(-1, 2)

    def rectify_point(self, u: float, v: float, side: str) -> tuple[float, float]:
        """One raw pixel ``(u, v)`` of a view (floats, finite) to its rectified pixel: the floats of
        :meth:`rectify_points`."""
        view = self.rectified_view(side)
        if view.undistorted:
            return view.rectify(u, v)
        a, b = self.rectify_points_fast(np.array([[u, v]]), side)[0].tolist()
        return a, b

    def rectified_view(self, side: str) -> "RectifiedView":
        """One view's camera, distortion and rectification, and the constants its per-point maps use;
        computed once per side (assigning a field starts again)."""
        return self._derived(side, lambda: RectifiedView(
            *((self.K_left, self.dist_left, self.R1, self.P1) if side == "left"
              else (self.K_right, self.dist_right, self.R2, self.P2))))

    def triangulate_rectified(self, uv_left_rect, uv_right_rect) -> np.ndarray:
        """Triangulate rectified pixels (same row, disparity ``u_l - u_r``) to ``p_cam`` (N, 3)."""
        l = as_points(uv_left_rect, "uv_left_rect", dim=2)
        r = as_points(uv_right_rect, "uv_right_rect", dim=2)
        disp = l[:, 0] - r[:, 0]
        hom = np.column_stack([l[:, 0], l[:, 1], disp, np.ones(len(l))]) @ self.Q.T
        with np.errstate(divide="ignore", invalid="ignore"):
            p_rect = hom[:, :3] / hom[:, 3:4]
        return p_rect @ self.R1  # rectified-left frame back to the left camera frame (R1^T p)

    def rectification_maps(self, side: str = "left") -> tuple[np.ndarray, np.ndarray]:
        """``cv2.remap`` maps (fixed-point, fast) from raw to rectified image; computed once."""
        v = self.rectified_view(side)
        return self._derived(f"maps_{side}", lambda: cv2.initUndistortRectifyMap(v.K, v.dist, v.R_rect, v.P,
                                                                                 self.image_size, cv2.CV_16SC2))

    def rectify_image(self, image: np.ndarray, side: str = "left") -> np.ndarray:
        """Warp a raw image of one camera into its rectified image."""
        m1, m2 = self.rectification_maps(side)
        return cv2.remap(image, m1, m2, cv2.INTER_LINEAR)

    # ------------------------------------------------------------------ files
    def to_filestorage_string(self) -> str:
        fs = cv2.FileStorage(".yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
        fs.startWriteStruct("image_size", cv2.FileNode_SEQ | cv2.FileNode_FLOW)
        for s in self.image_size:
            fs.write("", int(s))
        fs.endWriteStruct()
        # the names OpenCV's calibration sample writes, which its tools read
        fs.write("image_width", int(self.width))
        fs.write("image_height", int(self.height))
        for name, arr in self._arrays().items():
            fs.write(name, np.ascontiguousarray(arr, dtype=np.float64))
        if self.rms_px is not None:
            fs.write("rms_px", float(self.rms_px))
        if self.board is not None:
            fs.write("board", str(self.board))
        if self.board_size is not None:
            fs.write("board_width", int(self.board_size[0]))
            fs.write("board_height", int(self.board_size[1]))
        if self.square_m is not None:
            fs.write("square_size", float(self.square_m))
        return fs.releaseAndGetString()

    def save(self, path: str | os.PathLike) -> Path:
        """Write the rig as OpenCV FileStorage YAML (atomically: never a half-written file)."""
        return write_atomic(path, self.to_filestorage_string())

    @classmethod
    def load(cls, path: str | os.PathLike) -> "StereoRig":
        """Read a rig file; any problem raises one :class:`ConfigError` naming the file and field."""
        path = Path(path)
        nodes = read_filestorage(path)
        unknown = sorted(set(nodes) - _OTHER_NODES - set(_RECT_FIELDS) - {n for v in _MATRIX_NODES.values() for n in v})
        if unknown:
            raise ConfigError("unknown node; a rig file holds image_size, K1 D1 K2 D2 R T R1 R2 P1 P2 Q "
                              "(M1/M2 for K1/K2), rms_px, board, board_width, board_height, square_size",
                              file=path, field=unknown[0])
        size = _read_size(nodes, path)
        mats = {}
        for name, aliases in _MATRIX_NODES.items():
            present = [a for a in aliases if a in nodes]
            if len(present) > 1:
                raise ConfigError(f"both {present[0]} and {present[1]} are given", file=path, field=present[1])
            if not present:
                raise ConfigError("missing", file=path, field=name)
            mats[name] = _node_matrix(nodes, present[0], path)
        # rectification is required in a file (a truncated file loses it first)
        rect = {}
        for name in _RECT_FIELDS:
            if name not in nodes:
                raise ConfigError("missing", file=path, field=name)
            rect[name] = _node_matrix(nodes, name, path)
        extra = {}
        for name, key in (("rms_px", "rms_px"), ("square_size", "square_m")):
            if name in nodes:
                v = nodes[name]
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ConfigError(f"expected a number, got {v!r}", file=path, field=name)
                extra[key] = v
        if "board" in nodes:
            extra["board"] = nodes["board"]
        pattern = [k for k in ("board_width", "board_height") if k in nodes]
        if len(pattern) == 1:
            missing = ({"board_width", "board_height"} - set(pattern)).pop()
            raise ConfigError("missing (the pattern size needs board_width and board_height)", file=path, field=missing)
        if pattern:
            for k in pattern:
                if isinstance(nodes[k], bool) or not isinstance(nodes[k], int):
                    raise ConfigError(f"expected a whole number, got {nodes[k]!r}", file=path, field=k)
            extra["board_size"] = (nodes["board_width"], nodes["board_height"])
        try:
            return cls(
                image_size=size, K_left=mats["K1"], dist_left=mats["D1"], K_right=mats["K2"],
                dist_right=mats["D2"], R=mats["R"], T=mats["T"], **rect, **extra,
            )
        except ConfigError as exc:
            raise ConfigError(exc.reason, file=path, field=exc.field) from None

    def _arrays(self) -> dict[str, np.ndarray]:
        return {
            "K1": self.K_left, "D1": self.dist_left.reshape(1, -1), "K2": self.K_right,
            "D2": self.dist_right.reshape(1, -1), "R": self.R, "T": self.T.reshape(3, 1),
            "R1": self.R1, "R2": self.R2, "P1": self.P1, "P2": self.P2, "Q": self.Q,
        }

    def equals(self, other: "StereoRig") -> bool:
        """Exact equality of every parameter (bit for bit)."""
        if self.image_size != other.image_size:
            return False
        a, b = self._arrays(), other._arrays()
        info = ("rms_px", "board", "board_size", "square_m")
        return all(np.array_equal(a[k], b[k]) for k in a) and all(getattr(self, k) == getattr(other, k) for k in info)

    def summary(self) -> dict:
        """A JSON-ready description of the rig."""
        return {
            "image_size": list(self.image_size),
            "fx_px": self.fx_px,
            "hfov_deg": self.hfov_deg,
            "baseline_m": self.baseline_m,
            "rectified_fx_px": self.rectified_fx_px,
            "rectified_baseline_m": self.rectified_baseline_m,
            "distortion": bool(np.any(self.dist_left) or np.any(self.dist_right)),
            "rms_px": self.rms_px,
            "board": self.board,
            "board_size": None if self.board_size is None else list(self.board_size),
            "square_m": self.square_m,
        }


_FEW_POINTS = 4  # up to this many points are rectified in floats (one per candidate of a tracked view)
_UNDISTORT_CRIT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-14)


class RectifiedView:
    """One camera of a rig with its rectification (``K``, ``dist``, ``R_rect``, ``P``) and the floats
    of the maps between its raw and rectified pixels when it has no lens distortion
    (``undistorted``): :meth:`rectify` is cv2.undistortPoints' arithmetic for one point (the new
    camera matrix times the rectifying rotation, applied to ((u − cx)/fx, (v − cy)/fy); the camera's
    skew is not used there), :meth:`unrectify` cv2.projectPoints' after the rotation back."""

    def __init__(self, K: np.ndarray, dist: np.ndarray, R_rect: np.ndarray, P: np.ndarray):
        self.K, self.dist, self.R_rect, self.P = K, dist, R_rect, P
        self.undistorted = not np.count_nonzero(dist)
        self.skew_free = K[0, 1] == 0.0
        (k00, _, k02), (_, k11, k12), _ = K.tolist()
        self.ifx, self.ify, self.cx, self.cy = 1.0 / k00, 1.0 / k11, k02, k12
        self.fx, self.fy = k00, k11
        Pl, Rl = P[:, :3].tolist(), R_rect.tolist()
        # P[:, :3] · R_rect, each entry summed left to right (as OpenCV's 3×3 product)
        self.RR = tuple(Pl[i][0] * Rl[0][j] + Pl[i][1] * Rl[1][j] + Pl[i][2] * Rl[2][j]
                        for i in range(3) for j in range(3))
        self.R_entries = tuple(x for row in Rl for x in row)  # R_rect row by row
        (p00, _, p02, _), (_, p11, p12, _), _ = P.tolist()
        self.p00, self.p02, self.p11, self.p12 = p00, p02, p11, p12

    def rectify(self, u: float, v: float) -> tuple[float, float]:
        a, b, c, d, e, f, g, h, i = self.RR
        x, y = (u - self.cx) * self.ifx, (v - self.cy) * self.ify
        w = 1.0 / (g * x + h * y + i)
        return (a * x + b * y + c) * w, (d * x + e * y + f) * w

    def unrectify(self, u: float, v: float) -> tuple[float, float]:
        """A rectified pixel back to the raw pixel (a view without distortion or skew only)."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self.R_entries
        x, y = (u - self.p02) / self.p00, (v - self.p12) / self.p11
        iz = 1.0 / (x * r02 + y * r12 + r22)
        return (x * r00 + y * r10 + r20) * iz * self.fx + self.cx, (x * r01 + y * r11 + r21) * iz * self.fy + self.cy


def _as_field(make, name: str) -> np.ndarray:
    """Run a shape check, re-raising its error as a ConfigError on ``name``."""
    try:
        return make()
    except ConfigError:
        raise
    except VishapError as exc:
        raise ConfigError(str(exc).removeprefix(f"{name}: "), field=name) from None


def _check_rotation(R, name: str) -> np.ndarray:
    R = _as_field(lambda: as_array(R, (3, 3), name), name)
    if not is_rotation(R, tol=_ROT_TOL):
        raise ConfigError("not a proper rotation (orthonormal, det +1)", field=name)
    return R


def _check_K(K, name: str, image_size: tuple[int, int]) -> np.ndarray:
    K = _as_field(lambda: as_array(K, (3, 3), name), name)
    if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.array_equal(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0:
        raise ConfigError("not an intrinsic matrix (fx, fy > 0, last row [0 0 1])", field=name)
    w, h = image_size
    lo, hi = (r * max(w, h) for r in _FOCAL_RANGE)
    if not (lo <= K[0, 0] <= hi and lo <= K[1, 1] <= hi):
        raise ConfigError(f"focal lengths fx {K[0, 0]:.6g}, fy {K[1, 1]:.6g} px outside {lo:.6g}..{hi:.6g} px "
                          f"for a {w}x{h} image", field=name)
    if not (-w <= K[0, 2] <= 2 * w and -h <= K[1, 2] <= 2 * h) or abs(K[0, 1]) > K[0, 0]:
        raise ConfigError(f"principal point ({K[0, 2]:.6g}, {K[1, 2]:.6g}) or skew {K[0, 1]:.6g} implausible "
                          f"for a {w}x{h} image", field=name)
    return K


def _check_dist(d, name: str) -> np.ndarray:
    d = _as_field(lambda: np.asarray(d, dtype=np.float64).reshape(-1), name)
    if d.size not in _DIST_LENGTHS:
        raise ConfigError(f"expected {', '.join(map(str, _DIST_LENGTHS))} coefficients, got {d.size}", field=name)
    if not np.all(np.isfinite(d)):
        raise ConfigError("contains NaN or inf", field=name)
    if np.any(np.abs(d) > _MAX_DISTORTION):
        raise ConfigError(f"coefficient beyond ±{_MAX_DISTORTION:g}", field=name)
    return d


def _read_size(nodes: dict, path: Path) -> tuple[int, int]:
    def as_int(v, field):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(f"expected an integer, got {v!r}", file=path, field=field)
        return v

    size = None
    if "image_size" in nodes:
        v = nodes["image_size"]
        if not isinstance(v, list) or len(v) != 2:
            raise ConfigError(f"expected [width, height], got {v!r}", file=path, field="image_size")
        size = as_int(v[0], "image_size"), as_int(v[1], "image_size")
        if "image_width" not in nodes and "image_height" not in nodes:
            return size
    elif "image_width" not in nodes and "image_height" not in nodes:
        raise ConfigError("missing: add 'image_size: [width, height]' (OpenCV's stereo_calib sample does not "
                          "write the image size)", file=path, field="image_size")
    for k in ("image_width", "image_height"):
        if k not in nodes:
            raise ConfigError("missing", file=path, field=k)
    wh = as_int(nodes["image_width"], "image_width"), as_int(nodes["image_height"], "image_height")
    if size is not None and size != wh:
        raise ConfigError(f"image_size {list(size)} disagrees with image_width, image_height {list(wh)}",
                          file=path, field="image_size")
    return wh


def _node_matrix(nodes: dict, name: str, path: Path) -> np.ndarray:
    v = nodes[name]
    if not isinstance(v, np.ndarray):
        raise ConfigError("expected an !!opencv-matrix", file=path, field=name)
    return v
