"""The fabric demo: touch a fabric patch, rest on it, stroke it slowly then fast (HAPTEX §II-B
penalty contact with stick/slip friction; §II-C and PHSM §2 texture through the tactile layer)."""
from __future__ import annotations

import numpy as np

from vishap.apps.script import Z, FingerScript

__all__ = ["DEFAULT_FRAMES", "script", "surface", "extra_summary"]

DEFAULT_FRAMES = 120  # 4.0 s at 30 Hz


def script(hidden_s: float) -> FingerScript:
    return FingerScript(
        start=(0.240, 0.030, Z + 0.055),
        hidden_s=hidden_s,
        moves=(
            (0.25, (0.240, 0.030, Z + 0.055)),
            (1.00, (0.220, 0.005, Z)),           # approach and touch
            (0.30, (0.220, 0.005, Z - 0.002)),   # light press
            (0.40, (0.220, 0.005, Z - 0.002)),   # rest: a steady press
            (0.90, (0.185, 0.005, Z - 0.002)),   # slow stroke (≈ 0.04 m/s mean)
            (0.30, (0.215, 0.005, Z - 0.002)),   # fast stroke back (≈ 0.1 m/s mean, 0.19 peak)
            (0.50, (0.215, 0.005, Z + 0.045)),   # lift
        ),
    )


def extra_summary(meta: dict, ch: dict) -> dict:
    """Friction the device rendered while stroking (|F_t| / F_n of the force law) and slip time."""
    sv, tac = ch.get("servo", {}), ch.get("tactile", {})
    out: dict = {}
    if len(sv.get("t", [])):
        n = np.asarray(meta["object"]["normal"], float)
        F = sv["F_law"]
        fn = F @ n
        ft = np.linalg.norm(F - np.outer(fn, n), axis=1)
        v = sv["finger_velocity"]
        speed = np.linalg.norm(v - np.outer(v @ n, n), axis=1)
        stroke = sv["law_active"].astype(bool) & (fn > 0.05) & (speed > 0.01)
        out["stroke_ticks"] = int(stroke.sum())
        out["friction_ratio_median"] = float(np.median(ft[stroke] / fn[stroke])) if stroke.any() else None
    if len(tac.get("t", [])):
        out["slip_ms"] = float(np.sum(tac["state"] == 3) * np.median(np.diff(tac["t"])) * 1e3)
    return out


def surface(scene) -> dict:
    """Tactile attributes of the patch (PHSM §2.1): soft woven fabric; friction and weave period
    from the scene file (the same μ_k the force law renders)."""
    s = scene.objects[0].spec.surface
    return {"hardness": 0.2, "elasticity": 0.6, "roughness": min(1.0, 0.5 * s.roughness_rms_m / 5e-5),
            "friction": float(s.mu_kinetic), "viscoelasticity": 0.5, "texture_period_m": float(s.texture_period_m)}
