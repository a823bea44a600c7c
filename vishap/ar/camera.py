"""One calibrated camera of the rig, seen from the robot: projection and per-pixel viewing rays.

The augmented view is drawn for one camera (``left``, or ``right`` for a stereo display) at a time.
:class:`ViewCamera` holds that camera's pose in the robot frame (the calibration ``T_robot_cam``
of the left camera, and the rig's ``R``, ``T`` for the right one), projects robot-frame points with
the rig's own model (lens distortion included) and keeps, once, the undistorted viewing ray of
every pixel centre, so that planes can be ray-cast exactly under distortion.
"""
from __future__ import annotations

import numpy as np

from vishap._core.check import as_transform
from vishap._core.errors import ConfigError
from vishap._core.pose import invert
from vishap.vision.rig import StereoRig

__all__ = ["ViewCamera"]


class ViewCamera:
    """Camera ``side`` of ``rig`` with the left camera at ``T_robot_cam`` (4×4, left camera → robot)."""

    def __init__(self, rig: StereoRig, T_robot_cam, side: str = "left"):
        if side not in ("left", "right"):
            raise ConfigError(f"side must be 'left' or 'right', got {side!r}", field="side")
        self.rig = rig
        self.side = side
        self.T_robot_left = as_transform(T_robot_cam, "T_robot_cam")
        T_left_robot = invert(self.T_robot_left)
        T_side_left = np.eye(4)
        if side == "right":
            T_side_left[:3, :3] = rig.R
            T_side_left[:3, 3] = rig.T
        self.T_cam_robot = T_side_left @ T_left_robot      # this camera's frame ← robot
        self._T_left_robot = T_left_robot
        self.width, self.height = (int(v) for v in rig.image_size)
        self._rays = None

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    @property
    def position_robot(self) -> np.ndarray:
        return invert(self.T_cam_robot)[:3, 3]

    def to_cam(self, p_robot) -> np.ndarray:
        p = np.asarray(p_robot, dtype=np.float64).reshape(-1, 3)
        return p @ self.T_cam_robot[:3, :3].T + self.T_cam_robot[:3, 3]

    def project_cam(self, p_cam) -> np.ndarray:
        """(N, 2) pixels of points in *this* camera's frame (NaN behind the camera)."""
        p = np.asarray(p_cam, dtype=np.float64).reshape(-1, 3)
        if self.side == "right":  # the rig projects left-camera points into both views
            p = (p - self.rig.T) @ self.rig.R
        uv_l, uv_r = self.rig.project(p)
        return uv_l if self.side == "left" else uv_r

    def project_robot(self, p_robot) -> np.ndarray:
        return self.project_cam(self.to_cam(p_robot))

    def rays(self) -> np.ndarray:
        """(H, W, 3) float32 viewing rays (x/z, y/z, 1) of every pixel centre, undistorted; made once."""
        if self._rays is None:
            u, v = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
            xy = self.rig.undistort_normalized(np.stack([u.ravel(), v.ravel()], 1), self.side)
            rays = np.ones((self.height, self.width, 3), np.float32)
            rays[..., :2] = xy.reshape(self.height, self.width, 2)
            self._rays = rays
        return self._rays
