import numpy as np

from vishap.bench.world import _click, _line_fit
from vishap.world.force_laws import ButtonClick


def test_click_detector_finds_two_slopes_and_the_drop():
    law = ButtonClick([0, 0, 1], -0.15, trigger_depth_m=0.0018, travel_m=0.004, k_resist_n_m=350.0,
                      k_click_n_m=60.0, k_bottom_n_m=2500.0)
    d = np.r_[np.linspace(-0.002, 0.006, 800), np.linspace(0.006, 0.0, 400)]  # press in, release
    k1, k2, drop = _click(d, law.normal_force_curve(d))
    assert abs(k1 - 350.0) < 5 and abs(k2 - 60.0) < 5 and drop > 0.7
    assert _click(d, 400.0 * np.clip(d, 0, None)) is None or _click(d, 400.0 * np.clip(d, 0, None))[2] < 0.05


def test_line_fit_r2():
    d = np.linspace(0.001, 0.006, 50)
    slope, icpt, r2 = _line_fit(d, 444.0 * d - 0.1)
    assert abs(slope - 444.0) < 1e-6 and abs(r2 - 1.0) < 1e-12
