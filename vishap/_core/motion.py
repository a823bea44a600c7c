"""Minimum-jerk phase (Flash & Hogan): the smooth 0→1 profile every scripted finger motion uses."""
from __future__ import annotations

import numpy as np

__all__ = ["min_jerk", "min_jerk_rate"]


def min_jerk(s):
    """Phase 10s³ − 15s⁴ + 6s⁵ of ``s`` clipped to [0, 1] (zero velocity and acceleration at both ends)."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


def min_jerk_rate(s):
    """d/ds of :func:`min_jerk`: 30 s² (1 − s)², zero outside [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return 30.0 * s * s * (1.0 - s) ** 2
