"""The user's fingertip as the system models it: a hemispherical cap at the end of the finger.

Vision finds the cap's centre; the point that touches is the *pad*, one cap radius further along
the touched surface's inward normal. One home for the radius: the synthetic hand draws the same cap.
"""
from __future__ import annotations

__all__ = ["TIP_RADIUS_M"]

TIP_RADIUS_M = 0.008  # radius of the index fingertip's cap (adult index ≈ 16 mm wide), m
