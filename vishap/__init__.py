"""vishap: vision-centric, encountered-type augmented-reality haptics.

A stereo camera tracks a bare fingertip (``vishap.vision``), registration maps it into the robot
frame (``vishap.registration``), the world model picks the object and the device target
(``vishap.world``), a PHANToM-class arm meets the finger and renders the force law
(``vishap.robot``), and a finger-sleeve layer adds texture (``vishap.tactile``).

Units are SI everywhere (metres, seconds, newtons, radians, kilograms); pixels are float (u, v).
"""
from vishap._core.errors import (
    CalibrationError,
    ConfigError,
    DeviceError,
    ShapeError,
    VishapError,
    VisionError,
)

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "VishapError",
    "ConfigError",
    "CalibrationError",
    "DeviceError",
    "VisionError",
    "ShapeError",
]
