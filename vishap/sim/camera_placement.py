"""Where the synthetic stereo rig stands in the robot frame (the true ``T_robot_cam``).

The finger approaches the scene objects (on the plane z = −0.150 m around (0.200, 0, −0.150)) from
the user's side (+x) and points towards −x and down. A camera behind the user would look at the
back of the finger and lose the tip (a lesson of this project); the rig therefore looks at the
workspace from the front-left, elevated, so that the index finger is seen close to profile and its
rounded tip is the end of the finger's silhouette in both views (VisHap §3.2 detects exactly that).

Conventions: ``T_robot_cam`` maps left-camera coordinates (OpenCV: x right, y down, z forward) into
the robot frame (metres, z up).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["look_at", "default_T_robot_cam", "DEFAULT_TARGET_ROBOT", "DEFAULT_DISTANCE_M",
           "DEFAULT_AZIMUTH_DEG", "DEFAULT_ELEVATION_DEG"]

DEFAULT_TARGET_ROBOT = np.array([0.215, 0.0, -0.130])  # point the optical axis passes through, m
DEFAULT_DISTANCE_M = 0.55     # rig centre to target, m
DEFAULT_AZIMUTH_DEG = 235.0   # direction target→rig in the robot x-y plane (180° = towards the base)
DEFAULT_ELEVATION_DEG = 40.0  # rig above the horizontal through the target


def look_at(eye_robot, target_robot, up_robot=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``T_robot_cam`` of an OpenCV camera at ``eye`` looking at ``target`` with image-up ≈ ``up``
    (looking along ``up``, image x is robot x made orthogonal to the view)."""
    eye = np.asarray(eye_robot, dtype=np.float64)
    z = np.asarray(target_robot, dtype=np.float64) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up_robot, dtype=np.float64))
    if np.linalg.norm(x) < 1e-6:
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = eye
    return T


def default_T_robot_cam(
    *,
    baseline_m: float = 0.06,
    distance_m: float = DEFAULT_DISTANCE_M,
    azimuth_deg: float = DEFAULT_AZIMUTH_DEG,
    elevation_deg: float = DEFAULT_ELEVATION_DEG,
    target_robot=DEFAULT_TARGET_ROBOT,
) -> np.ndarray:
    """The camera-to-robot transform of the **left** camera used by all synthetic data.

    The rig's centre (midpoint of the two optical centres) sits ``distance_m`` from the target;
    the left camera is half a baseline to the left of it (the right camera is at +x of the left
    camera, as in :meth:`vishap.vision.rig.StereoRig.from_fov`). Returns a (4, 4) array.
    """
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    target = np.asarray(target_robot, dtype=np.float64)
    centre = target + distance_m * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    T_centre = look_at(centre, target)
    T = T_centre.copy()
    T[:3, 3] = centre - 0.5 * baseline_m * T_centre[:3, 0]
    return T
