"""What one synthetic frame shows (:class:`FrameState`) and what the renderer returns (:class:`RenderedPair`).

All positions are in the robot frame (metres, z up). The index fingertip is described by the centre
of its hemispherical cap (``tip_robot``), which is what VisHap's geometric detector locates (§3.2:
a circle of radius r = K/z at the end of the finger); the cap radius is :data:`TIP_RADIUS_M`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vishap.world.finger import TIP_RADIUS_M  # the one home of the cap radius (re-exported)

__all__ = ["TIP_RADIUS_M", "PassiveObject", "Occluder", "FrameState", "RenderedPair", "LABELS"]

#: label values of the per-pixel ground truth
LABELS = {"background": 0, "skin": 1, "device": 2, "object": 3}


@dataclass(frozen=True)
class PassiveObject:
    """The passive object carried by the device: a flat ``plate`` or a ``key``.

    ``size_m`` is (x, y, thickness). The object's **top face** is centred at
    ``ee_robot + mount_offset_robot`` (so its top face is the surface the finger touches); it is
    held by a short bracket from the end-effector, whose forearm would otherwise stand where the
    finger touches.
    """

    shape: str                                  # (the scene file's passive_object: its one home)
    size_m: tuple[float, float, float]
    mount_offset_robot: tuple[float, float, float]

    def top_centre_robot(self, ee_robot) -> np.ndarray:
        return np.asarray(ee_robot, dtype=np.float64) + np.asarray(self.mount_offset_robot, dtype=np.float64)

    def ee_for_contact(self, contact_robot) -> np.ndarray:
        """Where the end-effector must be for the object's top face to hold ``contact_robot``."""
        return np.asarray(contact_robot, dtype=np.float64) - np.asarray(self.mount_offset_robot, dtype=np.float64)


@dataclass(frozen=True)
class Occluder:
    """A dark rod (a pen, a tool) crossing the view: a capsule from ``a_robot`` to ``b_robot``."""

    a_robot: tuple[float, float, float]
    b_robot: tuple[float, float, float]
    radius_m: float = 0.006


@dataclass
class FrameState:
    """Everything that moves in one frame.

    Attributes
    ----------
    t: time of the frame, s.
    tip_robot: (3,) centre of the index fingertip's hemispherical cap, m.
    finger_dir_robot: (3,) unit direction of the distal phalanx (knuckle → tip).
    flexion: 0 (straight) … 1 (curled) bend of the index finger's joints.
    hand_visible: False leaves the hand out of the scene (hand-free frames).
    hand_roll: rotation of the hand about the finger direction, rad (0: back of the hand up).
    device_points_robot: (K, 3) polyline of the device's link joints, base → end-effector.
    ee_robot: (3,) end-effector point.
    passive_object: the carried object or None.
    marker: draw the pure-green 5 mm calibration sphere centred at ``ee_robot``.
    light: scale of every light's intensity (1 = nominal).
    occluder: an optional rod crossing the view.
    """

    t: float
    tip_robot: np.ndarray
    finger_dir_robot: np.ndarray = field(default_factory=lambda: np.array([-0.766, 0.0, -0.643]))
    flexion: float = 0.2
    hand_visible: bool = True
    hand_roll: float = 0.0
    device_points_robot: np.ndarray | None = None
    ee_robot: np.ndarray | None = None
    passive_object: PassiveObject | None = None
    marker: bool = False
    light: float = 1.0
    occluder: Occluder | None = None


@dataclass
class RenderedPair:
    """One rendered stereo pair: BGR ``uint8`` images, ``uint8`` labels, ``float32`` depth (m, 0 = none)."""

    left: np.ndarray
    right: np.ndarray
    labels_left: np.ndarray
    labels_right: np.ndarray
    depth_left: np.ndarray
    depth_right: np.ndarray
