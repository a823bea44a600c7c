"""The button and fabric demos end to end (rendered frames → vision → world → MuJoCo → tactile):
the physics each demo exists to show. Runs are on the simulated clock, so they do not depend on the
machine's load."""
import numpy as np
import pytest

from vishap.apps.config import DemoConfig
from vishap.apps.loop import run_demo

pytestmark = pytest.mark.render


def _run(tmp_path, scene, frames):
    cfg = DemoConfig(scene=scene, frames=frames, width=480, height=360, seed=2, video=False, save_frames=False)
    return run_demo(cfg, tmp_path)


def test_button_demo_clicks(tmp_path):
    s = _run(tmp_path, "button", 76)  # hidden frames, approach and the first press to the bottom
    assert s["approaches"] and s["approaches"][0]["lead_time_ms"] is not None and s["approaches"][0]["lead_time_ms"] > 0
    assert s["button_click_detected"], s
    # the force drops at the trigger and the key is stiffer before the click than after it
    assert s["button_force_after_click_n"] < 0.6 * s["button_force_before_click_n"]
    assert s["button_slope_before_click_n_per_mm"] > 0.1 and s["button_slope_before_click_n_per_mm"] > 3 * abs(s["button_slope_after_click_n_per_mm"])
    assert s["force_over_limit"] == 0 and s["nonfinite_commands"] == 0


def test_fabric_demo_rests_on_a_broad_patch_and_renders_friction(tmp_path):
    s = _run(tmp_path, "fabric", 120)
    assert s["approaches"][0]["lead_time_ms"] is not None and s["approaches"][0]["position_error_mm"] < 2.0
    # stroking: the force law's tangential/normal ratio is the patch's kinetic friction (scene: μk 0.35)
    assert s["stroke_ticks"] > 300 and s["friction_ratio_median"] == pytest.approx(0.35, abs=0.03)
    # the finger lies at 40° on the fabric: the sleeve sees a broad (distributed) contact while it rests
    states = s["tactile_state_ticks"]
    assert states["distributed"] > 300 and states["distributed"] > states["concentrated"]
    assert np.isfinite(s["max_contact_force_n"]) and s["max_force_n"] <= s["force_limit_n"] + 1e-9
