"""The device's silhouette in one camera image, from its joint state and the calibration.

Each convex part of :class:`~vishap.ar.device_geometry.DeviceGeometry` is projected through the
calibrated camera (:class:`~vishap.ar.camera.ViewCamera`, the rig's lens model) and filled as the
convex hull of its circumscribed outline points (``cv2.fillConvexPoly`` with sub-pixel vertices);
the union is grown by ``margin_px`` to cover the calibration's error and the camera's blur.
No renderer is needed: a frame costs a fraction of a millisecond.
"""
from __future__ import annotations

import cv2
import numpy as np

from vishap.ar.camera import ViewCamera
from vishap.ar.device_geometry import DeviceGeometry, part_hull_points_cam

__all__ = ["device_silhouette", "dilate"]

_SHIFT = 4  # fractional bits of the polygon vertices
_NEAR_M = 0.01


def dilate(mask: np.ndarray, radius_px: int) -> np.ndarray:
    """Grow a 0/255 mask by a disc of ``radius_px`` pixels (0: unchanged)."""
    r = int(radius_px)
    if r <= 0:
        return mask
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return cv2.dilate(mask, k)


def device_silhouette(geometry: DeviceGeometry, q, camera: ViewCamera, *, margin_px: int = 2) -> np.ndarray:
    """(H, W) uint8 mask, 255 where the device at joint angles ``q`` (rad) covers the image."""
    mask = np.zeros((camera.height, camera.width), np.uint8)
    groups = [pts for part in geometry.parts(q) for pts in part_hull_points_cam(part, camera.T_cam_robot)
              if np.all(pts[:, 2] >= _NEAR_M)]  # a part reaching behind the camera is not in this view
    if not groups:
        return mask
    uv_all = camera.project_cam(np.vstack(groups)) * float(1 << _SHIFT)  # one projection for every part
    start = 0
    for pts in groups:
        uv = uv_all[start:start + len(pts)]
        start += len(pts)
        if np.all(np.isfinite(uv)):
            hull = cv2.convexHull(np.round(uv).astype(np.int32).reshape(-1, 1, 2))
            cv2.fillConvexPoly(mask, hull, 255, cv2.LINE_8, _SHIFT)
    return dilate(mask, margin_px)
