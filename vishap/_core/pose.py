"""Rigid poses as 4×4 homogeneous matrices, with the frame convention in their names.

``T_robot_cam`` maps points expressed in the camera frame into the robot frame::

    p_robot = transform_points(T_robot_cam, p_cam)
    T_cam_robot = invert(T_robot_cam)
    T_a_c = T_a_b @ T_b_c

All translations are in metres, all angles in radians.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "from_rt",
    "identity",
    "invert",
    "transform_points",
    "transform_vectors",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotvec_to_matrix",
    "matrix_to_rotvec",
    "is_rotation",
    "rotation_angle",
]


def identity() -> np.ndarray:
    """The 4×4 identity transform."""
    return np.eye(4)


def from_rt(R, t) -> np.ndarray:
    """Build a 4×4 transform from a 3×3 rotation ``R`` and a translation ``t`` (metres)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=np.float64).reshape(3, 3)
    T[:3, 3] = np.asarray(t, dtype=np.float64).reshape(3)
    return T


def invert(T) -> np.ndarray:
    """Inverse of a rigid transform (uses Rᵀ, not a general matrix inverse)."""
    T = np.asarray(T, dtype=np.float64)
    R = T[:3, :3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ T[:3, 3]
    return out


def transform_points(T, p) -> np.ndarray:
    """Apply ``T`` to points ``p`` of shape (3,) or (N, 3); returns the same shape."""
    T = np.asarray(T, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    return p @ T[:3, :3].T + T[:3, 3]


def transform_vectors(T, v) -> np.ndarray:
    """Rotate free vectors (velocities, normals) ``v`` of shape (3,) or (N, 3) by ``T``."""
    T = np.asarray(T, dtype=np.float64)
    return np.asarray(v, dtype=np.float64) @ T[:3, :3].T


def rot_x(a: float) -> np.ndarray:
    """Rotation by ``a`` radians about x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation by ``a`` radians about y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation by ``a`` radians about z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotvec_to_matrix(rv) -> np.ndarray:
    """Rodrigues: axis·angle vector (radians) to rotation matrix."""
    rv = np.asarray(rv, dtype=np.float64).reshape(3)
    angle = float(np.linalg.norm(rv))
    if angle < 1e-300:
        return np.eye(3)
    k = rv / angle
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * Kx + (1.0 - np.cos(angle)) * (Kx @ Kx)


def matrix_to_rotvec(R) -> np.ndarray:
    """Rotation matrix to axis·angle vector (radians)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_rotvec()


def is_rotation(R, tol: float = 1e-6) -> bool:
    """True when ``R`` is orthonormal with determinant +1 (a proper rotation, not a reflection)."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        return False
    return bool(np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1.0) < tol)


def rotation_angle(R_a, R_b=None) -> float:
    """Angle (radians) of the rotation ``R_a`` (or of ``R_aᵀ R_b`` when ``R_b`` is given)."""
    R = np.asarray(R_a, dtype=np.float64)
    if R_b is not None:
        R = R.T @ np.asarray(R_b, dtype=np.float64)
    c = (np.trace(R) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))
