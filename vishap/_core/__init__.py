"""Conventions shared by every subpackage: errors, shape checks, poses, configuration files."""
from vishap._core.check import as_array, as_points, as_transform, check_finite, check_shape
from vishap._core.config import Schema, load_config, read_mapping, validate, write_atomic
from vishap._core.errors import (
    CalibrationError,
    ConfigError,
    DeviceError,
    ShapeError,
    VishapError,
    VisionError,
)

__all__ = [
    "VishapError",
    "ConfigError",
    "CalibrationError",
    "DeviceError",
    "VisionError",
    "ShapeError",
    "check_shape",
    "check_finite",
    "as_array",
    "as_points",
    "as_transform",
    "Schema",
    "read_mapping",
    "load_config",
    "validate",
    "write_atomic",
]
