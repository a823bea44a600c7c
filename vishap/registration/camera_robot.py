"""Camera-to-robot calibration files (VisHap §2.2, Eq. 3: ``ᴴP = ᴴ_C R ᶜP + t``).

A file holds ``T_robot_cam`` (maps the left camera frame of the rig into the robot frame), the
identity of the rig it was measured with (a fingerprint of its intrinsics, distortion and
extrinsics, so a transform is never used with another rig) and the calibration report::

    format: vishap.camera_robot/1
    T_robot_cam: [[r11, r12, r13, tx], [..], [..], [0, 0, 0, 1]]   # metres
    rig: {fingerprint: 3f2a…, image_size: [640, 480], fx_px: 554.3, baseline_m: 0.06}
    report: {poses_used: 12, per_axis_error_mm: [..], rms_mm: .., ...}

Every problem on load (missing, malformed, non-orthonormal, another rig) is one
:class:`~vishap._core.errors.CalibrationError` naming the file and field.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import Field

from vishap._core.config import Schema, read_mapping, validate, write_atomic
from vishap._core.errors import CalibrationError, ConfigError

__all__ = ["FORMAT", "rig_fingerprint", "rig_identity", "save", "load", "load_file", "CameraRobotFile"]

FORMAT = "vishap.camera_robot/1"
_ORTHO_TOL = 1e-6


def rig_fingerprint(rig) -> str:
    """A short stable hash of a :class:`~vishap.vision.rig.StereoRig`'s calibration (9 significant digits)."""
    parts = [f"{rig.image_size[0]}x{rig.image_size[1]}"]
    for arr in (rig.K_left, rig.dist_left, rig.K_right, rig.dist_right, rig.R, rig.T):
        parts.append(",".join(f"{float(v):.9g}" for v in np.asarray(arr, dtype=np.float64).ravel()))
    return hashlib.sha256(";".join(parts).encode()).hexdigest()[:16]


def rig_identity(rig) -> dict:
    """What a calibration file records about its rig."""
    return {
        "fingerprint": rig_fingerprint(rig),
        "image_size": [int(rig.image_size[0]), int(rig.image_size[1])],
        "fx_px": float(rig.fx_px),
        "baseline_m": float(rig.baseline_m),
    }


class _RigId(Schema):
    fingerprint: str = Field(min_length=4)
    image_size: list[int] = Field(min_length=2, max_length=2)
    fx_px: float
    baseline_m: float


class CameraRobotFile(Schema):
    """Schema of a camera-to-robot calibration file."""

    format: str
    T_robot_cam: list[list[float]]
    rig: _RigId | None = None
    report: dict[str, Any] = Field(default_factory=dict)


def _check_T(T: np.ndarray, path) -> np.ndarray:
    if T.shape != (4, 4):
        raise CalibrationError(f"expected a 4x4 matrix, got shape {T.shape}", file=path, field="T_robot_cam")
    if not np.all(np.isfinite(T)):
        raise CalibrationError("contains NaN or inf", file=path, field="T_robot_cam")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-12):
        raise CalibrationError(f"last row must be [0, 0, 0, 1], got {T[3].tolist()}", file=path, field="T_robot_cam")
    R = T[:3, :3]
    ortho = float(np.max(np.abs(R.T @ R - np.eye(3))))
    det = float(np.linalg.det(R))
    if ortho > _ORTHO_TOL or abs(det - 1.0) > _ORTHO_TOL:
        raise CalibrationError(
            f"rotation block is not a proper rotation (max |RᵀR − I| = {ortho:.2e}, det = {det:.6f}; "
            f"expected orthonormal with det +1 within {_ORTHO_TOL:g})", file=path, field="T_robot_cam")
    return T


def save(path: str | os.PathLike, T_robot_cam, report: dict | None = None, *, rig=None) -> Path:
    """Write a calibration file (atomically); ``rig`` ties it to that :class:`StereoRig`."""
    T = _check_T(np.asarray(T_robot_cam, dtype=np.float64), path)
    data = {
        "format": FORMAT,
        "T_robot_cam": [[float(v) for v in row] for row in T],
    }
    if rig is not None:
        data["rig"] = rig_identity(rig)
    data["report"] = _plain(report or {})
    text = ("# camera-to-robot calibration (VisHap Eq. 3): p_robot = T_robot_cam · p_cam, metres;\n"
            "# p_cam in the rig's left camera frame. Written by `vishap calibrate robot`.\n")
    text += yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)
    return write_atomic(path, text)


def load_file(path: str | os.PathLike, rig=None) -> CameraRobotFile:
    """Read and check a calibration file; with ``rig``, also check it was made for that rig."""
    try:
        doc = validate(CameraRobotFile, read_mapping(path), file=path)
    except CalibrationError:
        raise
    except ConfigError as exc:
        raise CalibrationError(exc.reason, file=path, field=exc.field) from None
    if doc.format != FORMAT:
        raise CalibrationError(f"expected format {FORMAT!r}, got {doc.format!r}", file=path, field="format")
    rows = doc.T_robot_cam
    if len(rows) != 4 or any(len(r) != 4 for r in rows):
        raise CalibrationError(f"expected a 4x4 matrix, got rows of lengths {[len(r) for r in rows]}",
                               file=path, field="T_robot_cam")
    _check_T(np.array(rows, dtype=np.float64), path)
    if rig is not None:
        if doc.rig is None:
            raise CalibrationError("file does not say which rig it was calibrated with; recalibrate",
                                   file=path, field="rig")
        fp = rig_fingerprint(rig)
        if doc.rig.fingerprint != fp:
            raise CalibrationError(
                f"calibrated for another rig (fingerprint {doc.rig.fingerprint}, {doc.rig.image_size[0]}x"
                f"{doc.rig.image_size[1]}, fx {doc.rig.fx_px:.1f} px, baseline {doc.rig.baseline_m * 1e3:.1f} mm) "
                f"but the rig in use is {fp} ({rig.image_size[0]}x{rig.image_size[1]}, fx {rig.fx_px:.1f} px, "
                f"baseline {rig.baseline_m * 1e3:.1f} mm); recalibrate with `vishap calibrate robot`",
                file=path, field="rig.fingerprint")
    return doc


def load(path: str | os.PathLike, rig=None) -> np.ndarray:
    """``T_robot_cam`` (4×4) from a calibration file (see :func:`load_file` for the checks)."""
    return np.array(load_file(path, rig).T_robot_cam, dtype=np.float64)


def _plain(obj):
    """Numpy values to plain YAML-safe Python."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
