"""Contact between the scripted finger's compliant pad and the device's passive object.

The finger is the user's, so its motion is scripted (kinematic); its pad is a penalty spring-damper
(HAPTEX §II-B penalty contact: force ∝ penetration). The passive object's top face (a plate or
key of ``size_m`` centred at the device's contact point) pushes back; the reaction is applied to
the device as an external tip force, so the device is *displaced* by the finger and renders the
object's force law against that displacement (VisHap §2.3, Fig. 6). Friction along the face is
the world's business (the fabric force law); the pad itself is frictionless.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["PadContact", "FingerPad"]


@lru_cache(maxsize=8)
def _basis(nx: float, ny: float, nz: float) -> tuple[np.ndarray, np.ndarray]:
    n = np.array([nx, ny, nz])
    ex = np.array([1.0, 0.0, 0.0]) - n * nx
    ex /= np.linalg.norm(ex)
    return ex, np.cross(n, ex)


@dataclass(frozen=True)
class PadContact:
    """One evaluation: ``overlap_m`` of pad into the face (> 0 touching), the force on the finger
    (N, robot frame; the device gets its negative), and the pad point's position on the face in the
    face's own frame (x, y in the face, z along the normal)."""

    in_contact: bool
    overlap_m: float
    force_on_finger: np.ndarray
    position_face: np.ndarray


@dataclass
class FingerPad:
    """Penalty pad: stiffness ``k_n_m`` (human fingertip ≈ 1–3 N/mm) and damping ``c_n_s_m``."""

    k_n_m: float = 1500.0
    c_n_s_m: float = 3.0
    max_overlap_m: float = 0.015  # deeper than this and the pad is beside, not on, the face

    def evaluate(self, pad_robot, pad_vel_robot, face_centre_robot, face_vel_robot, normal,
                 half_extent_m) -> PadContact:
        n = np.asarray(normal, float)
        rel = np.asarray(pad_robot, float) - np.asarray(face_centre_robot, float)
        overlap = -float(rel @ n)
        ex, ey = _basis(float(n[0]), float(n[1]), float(n[2]))
        pos = np.array([rel @ ex, rel @ ey, -overlap])
        inside = abs(pos[0]) <= half_extent_m[0] and abs(pos[1]) <= half_extent_m[1]
        if not (inside and 0.0 < overlap <= self.max_overlap_m):
            return PadContact(False, overlap, np.zeros(3), pos)
        closing = -float((np.asarray(pad_vel_robot, float) - np.asarray(face_vel_robot, float)) @ n)
        f = max(0.0, self.k_n_m * overlap + self.c_n_s_m * closing)
        return PadContact(True, overlap, f * n, pos)
