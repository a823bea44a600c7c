"""The button demo: press a virtual key B = (p, n, w, h) through its click to the bottom, twice
(VisHap §2.2–2.3 and Fig. 5–6 right: resistance spring, trigger, low stiffness, hard bottom)."""
from __future__ import annotations

import numpy as np

from vishap.apps.metrics import linear_fit
from vishap.apps.script import Z, FingerScript

__all__ = ["DEFAULT_FRAMES", "script", "surface", "extra_summary"]

DEFAULT_FRAMES = 133  # 4.4 s at 30 Hz


def script(hidden_s: float) -> FingerScript:
    return FingerScript(
        start=(0.230, 0.030, Z + 0.055),
        hidden_s=hidden_s,
        moves=(
            (0.25, (0.230, 0.030, Z + 0.055)),
            (1.00, (0.200, 0.000, Z)),           # approach the key's centre
            (0.80, (0.200, 0.000, Z - 0.0045)),  # press through the click to the bottom
            (0.20, (0.200, 0.000, Z - 0.0045)),
            (0.50, (0.200, 0.000, Z + 0.030)),   # release
            (0.35, (0.202, 0.002, Z)),           # quick second press
            (0.50, (0.202, 0.002, Z - 0.0045)),
            (0.50, (0.202, 0.002, Z + 0.045)),
        ),
    )


def extra_summary(meta: dict, ch: dict) -> dict:
    """The click: the normal force just before the trigger depth (its last 20 %), the force on the
    low-stiffness stretch after the click (past the drop, short of the bottom), and the two slopes."""
    from vishap.world.scene import load_scene

    sv = ch.get("servo", {})
    if not len(sv.get("t", [])):
        return {}
    key = load_scene(meta["config"]["scene"]).objects[0].spec
    d_trig, travel = float(key.trigger_depth_m), float(key.travel_m)
    n = np.asarray(meta["object"]["normal"], float)
    sel = sv["in_contact"].astype(bool)
    d, f = sv["device_depth"][sel], (sv["F_contact"] @ n)[sel]
    pre = (d > 0.1 * d_trig) & (d < 0.9 * d_trig)
    post = (d > d_trig + 0.15 * (travel - d_trig)) & (d < travel - 0.1 * (travel - d_trig))
    near_pre = (d > 0.8 * d_trig) & (d < d_trig)
    f_pre = float(np.median(f[near_pre])) if near_pre.any() else None
    f_post = float(np.median(f[post])) if post.any() else None
    return {
        "button_trigger_depth_mm": 1e3 * d_trig,
        "button_max_depth_mm": float(1e3 * d.max()) if d.size else None,
        "button_slope_before_click_n_per_mm": linear_fit(d[pre], f[pre])[0] * 1e-3 if pre.sum() > 2 else None,
        "button_slope_after_click_n_per_mm": linear_fit(d[post], f[post])[0] * 1e-3 if post.sum() > 2 else None,
        "button_force_before_click_n": f_pre,
        "button_force_after_click_n": f_post,
        "button_click_detected": bool(f_pre is not None and f_post is not None and f_post < f_pre),
    }


def surface(scene) -> dict:
    """Tactile attributes of a keycap (PHSM §2.1): hard plastic, smooth, a fine grain."""
    return {"hardness": 0.85, "elasticity": 0.15, "roughness": 0.2, "friction": 0.35, "viscoelasticity": 0.1,
            "texture_period_m": 0.0008}
