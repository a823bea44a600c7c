"""The wall demo: touch a virtual plane P = (n, d), press, slide along it, touch again fast (VisHap
§2.2 "Scene Configuration", §3 Fig. 6 left: force along the normal is a linear spring in depth)."""
from __future__ import annotations

import numpy as np

from vishap.apps.script import Z, FingerScript

__all__ = ["DEFAULT_FRAMES", "script", "surface", "extra_summary"]

DEFAULT_FRAMES = 162  # 5.4 s at 30 Hz: the script below plus its 10 hand-free frames


def script(hidden_s: float) -> FingerScript:
    return FingerScript(
        start=(0.235, 0.035, Z + 0.055),
        hidden_s=hidden_s,
        moves=(
            (0.25, (0.235, 0.035, Z + 0.055)),   # appear, pause
            (1.00, (0.215, 0.010, Z)),           # approach (peak ≈ 0.1 m/s) and touch
            (0.40, (0.215, 0.010, Z - 0.003)),   # press 3 mm
            (0.30, (0.215, 0.010, Z - 0.003)),   # hold
            (0.80, (0.190, -0.010, Z - 0.003)),  # slide 32 mm along the wall
            (0.50, (0.190, -0.010, Z + 0.040)),  # lift
            (0.45, (0.225, -0.020, Z + 0.050)),  # move over
            (0.30, (0.225, -0.020, Z)),          # fast approach (peak ≈ 0.3 m/s)
            (0.50, (0.225, -0.020, Z - 0.005)),  # press 5 mm
            (0.50, (0.225, -0.020, Z + 0.045)),  # lift
        ),
    )


def extra_summary(meta: dict, ch: dict) -> dict:
    """Slide tracking: how far the device's contact point lagged the finger while sliding."""
    sv = ch.get("servo", {})
    if not len(sv.get("t", [])):
        return {}
    n = np.asarray(meta["object"]["normal"], float)
    touching = sv["in_contact"].astype(bool)
    if not touching.any():
        return {"slide_lag_mm_median": None}
    d = sv["finger_point"][touching] - sv["device_point"][touching]
    lateral = d - np.outer(d @ n, n)
    return {"slide_lag_mm_median": float(1e3 * np.median(np.linalg.norm(lateral, axis=1)))}


def surface(scene) -> dict:
    """Tactile attributes of the plate the finger meets (PHSM §2.1): hard, smooth, little texture."""
    return {"hardness": 0.95, "elasticity": 0.05, "roughness": 0.1, "friction": 0.3, "viscoelasticity": 0.05,
            "texture_period_m": 0.002}
