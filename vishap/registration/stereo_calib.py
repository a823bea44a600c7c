"""Stereo calibration from views of a planar board (chessboard or ChArUco).

VisHap (§2, §2.1) relies on calibrated stereo cameras to put the fingertip in the left camera's
frame; this module produces that calibration as a :class:`vishap.vision.rig.StereoRig` (with
rectification). Procedure (Zhang's method as OpenCV implements it):

1. find the board in every left/right pair (chessboard: ``cv2.findChessboardCorners`` at scale
   1, then 2, refined by ``cv2.cornerSubPix``; ChArUco: ``cv2.aruco.CharucoDetector``, corners
   paired by id across the two images);
2. calibrate each camera alone (``cv2.calibrateCamera``, 5-coefficient distortion by default);
3. refine both cameras and their relative pose together (``cv2.stereoCalibrate`` starting from
   step 2) and report the stereo reprojection RMS in pixels.

OpenCV's ``stereo_calib.cpp`` sample instead starts from ``initCameraMatrix2D`` and constrains
the model (same focal length, fixed aspect ratio, no tangential terms, rational k1 k2 k6). The
per-camera start lets the joint refinement reach a lower RMS on the same images (see
``docs/registration.md`` and ``tests/registration/test_stereo_calib.py``).
"""
from __future__ import annotations

import glob
import os
from dataclasses import dataclass, field

import cv2
import numpy as np

from vishap._core.errors import CalibrationError, ConfigError
from vishap.vision.rig import StereoRig

__all__ = ["Board", "detect_board", "StereoCalibration", "calibrate_stereo", "calibrate_stereo_files", "parse_board",
           "opencv_sample_stereo_calib", "expand_glob"]

_SUBPIX = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 30, 0.01)
_MODELS = {
    "k5": 0,  # k1 k2 p1 p2 k3
    "k4": cv2.CALIB_FIX_K3,  # k1 k2 p1 p2
    "rational": cv2.CALIB_RATIONAL_MODEL,  # k1..k6 p1 p2
}


@dataclass(frozen=True)
class Board:
    """A planar calibration target.

    ``cols`` × ``rows``: inner corners for a chessboard, squares for a ChArUco board.
    ``square_m``: side of one square (metres). ``marker_m`` and ``dictionary``: ChArUco only.
    """

    cols: int
    rows: int
    square_m: float
    kind: str = "chessboard"
    marker_m: float | None = None
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2:
            raise ConfigError(f"board must be at least 2x2, got {self.cols}x{self.rows}", field="board")
        if not self.square_m > 0:
            raise ConfigError(f"square size must be positive metres, got {self.square_m}", field="square")
        if self.kind not in ("chessboard", "charuco"):
            raise ConfigError(f"board kind must be chessboard or charuco, got {self.kind!r}", field="board")
        if self.kind == "charuco":
            if self.marker_m is None or not (0 < self.marker_m < self.square_m):
                raise ConfigError(f"ChArUco marker size must be in (0, square), got {self.marker_m}", field="marker")
            if not hasattr(cv2.aruco, self.dictionary):
                raise ConfigError(f"unknown ArUco dictionary {self.dictionary!r}", field="dictionary")

    @property
    def object_points(self) -> np.ndarray:
        """Board corners in the board frame (metres, z = 0), in detection order (N, 3) float32."""
        if self.kind == "charuco":
            return self.charuco_board().getChessboardCorners().astype(np.float32)
        obj = np.zeros((self.cols * self.rows, 3), np.float32)
        obj[:, :2] = np.mgrid[0 : self.cols, 0 : self.rows].T.reshape(-1, 2) * self.square_m
        return obj

    def charuco_board(self):
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square_m, self.marker_m, d)


def parse_board(text: str, square_m: float, *, charuco: bool = False, marker_m: float | None = None,
                dictionary: str = "DICT_4X4_50") -> Board:
    """``'9x6'`` → :class:`Board` (inner corners for a chessboard, squares for ChArUco)."""
    try:
        cols, rows = (int(s) for s in text.lower().split("x"))
    except ValueError:
        raise ConfigError(f"expected COLSxROWS such as 9x6, got {text!r}", field="board") from None
    return Board(cols, rows, square_m, "charuco" if charuco else "chessboard", marker_m, dictionary)


def _gray(image) -> np.ndarray:
    if isinstance(image, (str, os.PathLike)):
        img = cv2.imread(str(image), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise CalibrationError("cannot read image", file=image)
        return img
    img = np.asarray(image)
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img


def detect_board(image, board: Board) -> tuple[np.ndarray, np.ndarray] | None:
    """Find the board in one image: ``(ids (N,), uv (N, 2) float32)`` sub-pixel, or ``None``.

    For a chessboard the ids are 0…cols·rows−1 (all corners or nothing); for ChArUco, the ids of
    the corners found (at least 6 needed).
    """
    gray = _gray(image)
    if board.kind == "charuco":
        det = cv2.aruco.CharucoDetector(board.charuco_board())
        corners, ids, _, _ = det.detectBoard(gray)
        if ids is None or len(ids) < 6:
            return None
        return ids.reshape(-1).astype(int), corners.reshape(-1, 2).astype(np.float32)
    size = (board.cols, board.rows)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    for scale in (1, 2):
        img = gray if scale == 1 else cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR_EXACT)
        found, corners = cv2.findChessboardCorners(img, size, flags=flags)
        if found:
            corners = (corners / scale).astype(np.float32)
            corners = cv2.cornerSubPix(gray, corners, (11, 11), (-1, -1), _SUBPIX)
            return np.arange(len(corners)), corners.reshape(-1, 2)
    return None


@dataclass
class StereoCalibration:
    """Result of :func:`calibrate_stereo`: the rig and how well it fits the views."""

    rig: StereoRig
    rms_px: float
    pairs_used: int
    pairs_total: int
    per_view_rms_px: np.ndarray  # (pairs_used, 2): left, right
    mono_rms_px: tuple[float, float]
    used: list[int] = field(default_factory=list)  # indices of the pairs used

    def summary(self) -> dict:
        return {
            "pairs_used": self.pairs_used,
            "pairs_total": self.pairs_total,
            "rms_px": self.rms_px,
            "mono_rms_px": list(self.mono_rms_px),
            "baseline_m": self.rig.baseline_m,
            "fx_px": self.rig.fx_px,
            "fx_right_px": float(self.rig.K_right[0, 0]),
            "rectified_fx_px": self.rig.rectified_fx_px,
            "image_size": list(self.rig.image_size),
            "worst_view_rms_px": float(np.max(self.per_view_rms_px)) if len(self.per_view_rms_px) else None,
        }


def calibrate_stereo(left, right, board: Board, *, model: str = "k5", progress: bool = False) -> StereoCalibration:
    """Calibrate a stereo pair from matching sequences of left/right images (paths or arrays);
    ``progress``: a bar over the pairs, on stderr on a terminal."""
    from vishap._core.results import progress as bar

    if model not in _MODELS:
        raise ConfigError(f"distortion model must be one of {sorted(_MODELS)}, got {model!r}", field="model")
    left, right = list(left), list(right)
    if len(left) != len(right):
        raise CalibrationError(f"{len(left)} left images but {len(right)} right images")
    obj_all = board.object_points
    objs, img_l, img_r, used = [], [], [], []
    size = None
    first = None
    for i, (a, b) in enumerate(bar(zip(left, right), total=len(left), desc="calibrate stereo", unit="pair",
                                   quiet=not progress)):
        ga, gb = _gray(a), _gray(b)
        s, sb = (ga.shape[1], ga.shape[0]), (gb.shape[1], gb.shape[0])
        if sb != s:
            raise CalibrationError(f"pair {i}: {_name(b, 'right')} is {_wxh(sb)} but {_name(a, 'left')} is {_wxh(s)}")
        if size is not None and s != size:
            raise CalibrationError(f"pair {i}: {_name(a, 'left')} is {_wxh(s)} but the first pair "
                                   f"({_name(first, 'left')}) is {_wxh(size)}; every image must have one size")
        size, first = s, (a if first is None else first)
        da, db = detect_board(ga, board), detect_board(gb, board)
        if da is None or db is None:
            continue
        common, ia, ib = np.intersect1d(da[0], db[0], return_indices=True)
        if len(common) < 6:
            continue
        objs.append(obj_all[common])
        img_l.append(da[1][ia].reshape(-1, 1, 2))
        img_r.append(db[1][ib].reshape(-1, 1, 2))
        used.append(i)
    if len(used) < 3:
        raise CalibrationError(f"the board ({board.cols}x{board.rows} {board.kind}) was found in both images of "
                               f"only {len(used)} of {len(left)} pairs; need at least 3")
    flags = _MODELS[model]
    rms_l, K1, D1, _, _ = cv2.calibrateCamera(objs, img_l, size, None, None, flags=flags)
    rms_r, K2, D2, _, _ = cv2.calibrateCamera(objs, img_r, size, None, None, flags=flags)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-9)
    out = cv2.stereoCalibrateExtended(
        objs, img_l, img_r, K1, D1, K2, D2, size, None, None,
        flags=cv2.CALIB_USE_INTRINSIC_GUESS | flags, criteria=crit,
    )
    rms, K1, D1, K2, D2, R, T = out[:7]
    per_view = np.asarray(out[-1], dtype=np.float64).reshape(len(used), 2)
    if not np.isfinite(rms):
        raise CalibrationError("stereo calibration diverged (non-finite reprojection error)")
    # the rig file records what the calibration was made from and how well it fits
    rig = StereoRig(image_size=size, K_left=K1, dist_left=D1, K_right=K2, dist_right=D2, R=R, T=T.reshape(3),
                    rms_px=float(rms), board=board.kind, board_size=(board.cols, board.rows), square_m=board.square_m)
    return StereoCalibration(rig, float(rms), len(used), len(left), per_view, (float(rms_l), float(rms_r)), used)


def _name(image, side: str) -> str:
    """An image for a message: its file name when it came from a file."""
    return str(image) if isinstance(image, (str, os.PathLike)) else f"the {side} image"


def _wxh(size: tuple[int, int]) -> str:
    return f"{size[0]}x{size[1]}"


def expand_glob(pattern: str) -> list[str]:
    """Sorted files matching a glob (``~`` expanded); a pattern that matches nothing is an error."""
    files = sorted(glob.glob(os.path.expanduser(pattern)))
    if not files:
        raise CalibrationError(f"no files match {pattern!r}")
    return files


def calibrate_stereo_files(left_glob: str, right_glob: str, board: Board, *, model: str = "k5",
                           progress: bool = False) -> StereoCalibration:
    """:func:`calibrate_stereo` on two globs, paired in sorted order."""
    lf, rf = expand_glob(left_glob), expand_glob(right_glob)
    if len(lf) != len(rf):
        raise CalibrationError(f"{left_glob!r} matches {len(lf)} files but {right_glob!r} matches {len(rf)}")
    return calibrate_stereo(lf, rf, board, model=model, progress=progress)


def opencv_sample_stereo_calib(left, right, board: Board) -> dict:
    """The procedure of OpenCV's ``samples/cpp/stereo_calib.cpp``, call for call, as a reference.

    Same detection (scale 1 and 2, ``cornerSubPix`` 11×11), ``initCameraMatrix2D`` start and the
    sample's flags and termination criteria. Returns ``{"pairs_used", "rms_px", "baseline_m"}``.
    """
    if board.kind != "chessboard":
        raise ConfigError("the OpenCV sample uses a chessboard", field="board")
    objs, img_l, img_r = [], [], []
    size = None
    for a, b in zip(left, right):
        ga, gb = _gray(a), _gray(b)
        size = (ga.shape[1], ga.shape[0])
        da, db = detect_board(ga, board), detect_board(gb, board)
        if da is None or db is None:
            continue
        objs.append(board.object_points)
        img_l.append(da[1].reshape(-1, 1, 2))
        img_r.append(db[1].reshape(-1, 1, 2))
    if len(objs) < 2:
        raise CalibrationError(f"board found in only {len(objs)} pairs; the sample needs 2")
    K1 = cv2.initCameraMatrix2D(objs, img_l, size, 0)
    K2 = cv2.initCameraMatrix2D(objs, img_r, size, 0)
    flags = (cv2.CALIB_FIX_ASPECT_RATIO + cv2.CALIB_ZERO_TANGENT_DIST + cv2.CALIB_USE_INTRINSIC_GUESS
             + cv2.CALIB_SAME_FOCAL_LENGTH + cv2.CALIB_RATIONAL_MODEL + cv2.CALIB_FIX_K3 + cv2.CALIB_FIX_K4
             + cv2.CALIB_FIX_K5)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-5)
    rms, K1, D1, K2, D2, R, T, _, _ = cv2.stereoCalibrate(objs, img_l, img_r, K1, None, K2, None, size,
                                                          flags=flags, criteria=crit)
    return {"pairs_used": len(objs), "rms_px": float(rms), "baseline_m": float(np.linalg.norm(T)),
            "fx_px": float(K1[0, 0])}
