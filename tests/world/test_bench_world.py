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


def test_perfect_prediction_bound_runs_on_the_world_and_puts_the_device_in_place():
    """The bench's perfect-prediction world overrides the world's target: it must keep the world's
    signature (it once crashed the sensitivity rows) and, told the touch point, be in place."""
    import pytest

    pytest.importorskip("mujoco")
    from vishap.bench.world import _perfect_world_class
    from vishap.world.closed_loop import VisionModel, run_approach
    from vishap.world.scene import load_scene
    from vishap.world.trajectories import make_approaches

    scene = load_scene("wall")
    tr = make_approaches(scene, 1, speeds=(0.2,), seed=3, slide=False)[0]
    w = _perfect_world_class()(scene, latency_s=0.033, contact_model="both")
    w.truth(tr, None)
    r = run_approach(scene, tr, w, vision=VisionModel(), stop_after_contact_s=0.02)
    assert r.in_place and r.contact_error_m < 0.001


def test_the_perfect_path_bound_readies_a_device_the_still_bound_cannot():
    """A finger landing while it slides sideways (0.2 m/s reach): told the touch point, the device
    waits there still and fails ``still_tangential``; told the finger's path (``perfect_path``), it runs
    up with the finger and is ready — the bound on readiness the servo side allows."""
    import pytest

    pytest.importorskip("mujoco")
    from vishap.bench.world import _perfect_world_class
    from vishap.world.closed_loop import VisionModel, run_approach
    from vishap.world.scene import load_scene
    from vishap.world.trajectories import make_approaches

    scene = load_scene("wall")
    tr = make_approaches(scene, 40, seed=7, bow_fraction=0.10, slide=False)[6]
    out = {}
    for path in (False, True):
        w = _perfect_world_class()(scene, latency_s=0.033, contact_model="both")
        w.truth(tr, None, path=path)
        out[path] = run_approach(scene, tr, w, vision=VisionModel(), stop_after_contact_s=0.02)
    assert out[False].in_place and not out[False].ready_checks["still_tangential"]
    assert out[True].ready and out[True].contact_error_m < 0.001
