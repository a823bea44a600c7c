"""One error hierarchy for the whole package.

Every failure that a user can cause (a bad file, a bad value, an unreachable device) is raised as a
subclass of :class:`VishapError` whose message names the file and/or the field and what was
expected, so that the command line can print it as one clear line.
"""
from __future__ import annotations

from os import PathLike

__all__ = [
    "VishapError",
    "ConfigError",
    "CalibrationError",
    "DeviceError",
    "VisionError",
    "ShapeError",
]


class VishapError(Exception):
    """Base of every error vishap raises on purpose."""


class ConfigError(VishapError, ValueError):
    """A configuration file or value is missing, malformed or out of range.

    Parameters
    ----------
    message:
        What was wrong and what was expected.
    file:
        The file it came from, if any.
    field:
        The field (dotted path, e.g. ``walls.0.normal``) it concerns, if any.
    """

    def __init__(self, message: str, *, file: str | PathLike | None = None, field: str | None = None):
        self.file = None if file is None else str(file)
        self.field = field
        self.reason = message
        parts = []
        if self.file is not None:
            parts.append(f"{self.file}")
        if field is not None:
            parts.append(f"field '{field}'")
        prefix = ": ".join(parts)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class CalibrationError(ConfigError):
    """A calibration (rig, camera-to-robot transform) is missing, malformed or inconsistent."""


class DeviceError(VishapError, RuntimeError):
    """The haptic device (simulated or real) cannot be reached or refused a command."""


class VisionError(VishapError, RuntimeError):
    """A camera, video or frame source failed (missing device, corrupt frame, mismatched pair)."""


class ShapeError(VishapError, ValueError):
    """An array argument has the wrong shape, dtype or non-finite values."""
