"""Drawing the haptic device, and a stand-in arm for scripted sequences.

The renderer draws whatever polyline of link joints it is given (``device_points_robot``, base →
end-effector) as dark grey links with black joints, so that the device never looks like skin (a
lesson of this project: a moving device that reads as foreground breaks the background model).

:func:`phantom_link_points` is the drawing-only geometry of a PHANToM-class 3-DOF arm (shoulder at
the origin, upper arm l1, forearm l2, elbow up) used when a sequence is scripted without the robot
package; the demos pass the link points of :mod:`vishap.robot.kinematics` instead.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["L1_M", "L2_M", "TABLE_Z_M", "REACHABLE_BOX", "phantom_link_points", "clip_to_reachable"]

L1_M = 0.215        # upper arm, shoulder → elbow (PHANToM Premium 1.0), m
L2_M = 0.170        # forearm, elbow → end-effector, m
TABLE_Z_M = -0.260  # the table the device base stands on, m
REACHABLE_BOX = np.array([[0.10, -0.065, -0.20], [0.30, 0.065, -0.04]])  # shared by all areas, m


def clip_to_reachable(p_robot) -> np.ndarray:
    return np.clip(np.asarray(p_robot, dtype=np.float64), REACHABLE_BOX[0], REACHABLE_BOX[1])


def phantom_link_points(ee_robot) -> np.ndarray:
    """(5, 3) polyline: base foot on the table, base top, shoulder, elbow, end-effector (robot frame).

    Two-link inverse kinematics in the vertical plane through the end-effector, elbow up; a point
    out of reach is drawn with the arm stretched towards it.
    """
    ee = np.asarray(ee_robot, dtype=np.float64)
    yaw = math.atan2(ee[1], ee[0])
    r = math.hypot(ee[0], ee[1])
    z = ee[2]
    d = min(math.hypot(r, z), L1_M + L2_M - 1e-9)
    cos_sh = (L1_M**2 + d**2 - L2_M**2) / (2 * L1_M * d)
    a_sh = math.atan2(z, r) + math.acos(float(np.clip(cos_sh, -1.0, 1.0)))
    elbow_rz = L1_M * np.array([math.cos(a_sh), math.sin(a_sh)])
    elbow = np.array([elbow_rz[0] * math.cos(yaw), elbow_rz[0] * math.sin(yaw), elbow_rz[1]])
    shoulder = np.zeros(3)
    base_top = np.array([-0.02, 0.0, -0.06])
    foot = np.array([-0.02, 0.0, TABLE_Z_M])
    return np.stack([foot, base_top, shoulder, elbow, ee])
