"""Drawing the haptic device, and a stand-in arm for scripted sequences.

The renderer draws whatever polyline of link joints it is given (``device_points_robot``, base →
end-effector) as dark grey links with black joints, so that the device never looks like skin (a
lesson of this project: a moving device that reads as foreground breaks the background model).

:func:`phantom_link_points` is the drawing-only geometry of a PHANToM-class 3-DOF arm (shoulder at
the origin, upper arm l1, forearm l2, elbow up) used when a sequence is scripted without the robot
package; the demos pass the link points of :mod:`vishap.robot.kinematics` instead.

:func:`encounter_ee` is the device's path in scripted sequences: like the encountered-type device
of VisHap §2.3 it holds its passive object's top face under the finger (at the surface, inside the
scene's opening), and :func:`device_links` draws it with the PHANToM's kinematics.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["L1_M", "L2_M", "TABLE_Z_M", "REACHABLE_BOX", "phantom_link_points", "clip_to_reachable", "plate_region",
           "touch_region", "encounter_ee", "device_links"]

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


# ---------------------------------------------------------------------- encountered-type device path
_CLEARANCE_M = 0.001   # gap kept between the passive object and the drawn object's frame
_TOUCH_MARGIN_M = 0.004  # the finger's contact point stays this far inside the passive object's top face


def plate_region(spec, passive) -> np.ndarray:
    """((x_min, y_min), (x_max, y_max)) of the passive object's top-face centre inside the scene's opening."""
    from vishap.sim.scene_objects import opening_half_extent

    hx, hy = opening_half_extent(spec)
    cx, cy = spec.centre_robot[0], spec.centre_robot[1]
    mx = max(0.0, hx - passive.size_m[0] / 2.0 - _CLEARANCE_M)
    my = max(0.0, hy - passive.size_m[1] / 2.0 - _CLEARANCE_M)
    return np.array([[cx - mx, cy - my], [cx + mx, cy + my]])


def touch_region(spec, passive) -> np.ndarray:
    """Where the finger may touch: wherever some allowed position of the passive object lies under it."""
    reg = plate_region(spec, passive)
    half = np.array(passive.size_m[:2]) / 2.0 - _TOUCH_MARGIN_M
    return np.array([reg[0] - half, reg[1] + half])


def encounter_ee(spec, passive, tip_robot, depth_m: float = 0.0) -> np.ndarray:
    """End-effector position that holds the passive object's top face under the fingertip.

    The encountered-type device waits where the finger will touch (VisHap §2.3): the top face is
    centred under the fingertip's (x, y), clipped into the scene's opening, at the surface height
    (pushed down by ``depth_m`` when the finger presses the surface in, e.g. a key). The result lies
    in :data:`REACHABLE_BOX` (a :class:`ValueError` otherwise: the scene does not fit the device).
    """
    reg = plate_region(spec, passive)
    xy = np.clip(np.asarray(tip_robot, dtype=np.float64)[:2], reg[0], reg[1])
    top = np.array([xy[0], xy[1], spec.surface_z_m - float(depth_m)])
    ee = passive.ee_for_contact(top)
    if np.any(ee < REACHABLE_BOX[0] - 1e-9) or np.any(ee > REACHABLE_BOX[1] + 1e-9):
        raise ValueError(f"end-effector {ee.tolist()} for scene {spec.name!r} is outside the reachable box")
    return ee


def device_links(ee_robot) -> np.ndarray:
    """(5, 3) polyline of the PHANToM at ``ee_robot``: its foot on the table, then
    :func:`vishap.robot.kinematics.link_points` (base, shoulder, elbow, end-effector) of ``ik(ee)``."""
    from vishap.robot.kinematics import ik, link_points

    pts = link_points(ik(np.asarray(ee_robot, dtype=np.float64)))
    foot = np.array([pts[0, 0], pts[0, 1], TABLE_Z_M])  # the base stands on the table
    return np.vstack([foot, pts])
