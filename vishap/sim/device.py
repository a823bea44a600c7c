"""The haptic device in scripted sequences: where it waits and how it is drawn.

The renderer draws whatever polyline of link joints it is given (``device_points_robot``, base →
end-effector) as dark grey links with black joints, so that the device never looks like skin (a
lesson of this project: a moving device that reads as foreground breaks the background model).
The arm's geometry and workspace are the robot's (:mod:`vishap.robot.kinematics`,
:mod:`vishap.robot.params`); nothing here models the arm again.

:func:`encounter_ee` is the device's path in scripted sequences: like the encountered-type device
of VisHap §2.3 it holds its passive object's top face under the finger (at the surface, inside the
scene's opening), and :func:`device_links` draws it with the PHANToM's kinematics.
"""
from __future__ import annotations

import numpy as np

from vishap.robot.params import WORKSPACE_MAX, WORKSPACE_MIN

__all__ = ["TABLE_Z_M", "REACHABLE_BOX", "plate_region", "touch_region", "encounter_ee", "device_links"]

TABLE_Z_M = -0.260  # the table the device base stands on, m
#: the device's workspace box ((min), (max), robot frame, m): the robot's own limits
REACHABLE_BOX = np.array([WORKSPACE_MIN, WORKSPACE_MAX], dtype=np.float64)


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
