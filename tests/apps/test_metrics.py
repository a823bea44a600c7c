import numpy as np
import pytest

from vishap.apps.metrics import approaches, force_depth_r2, linear_fit, rising_edges, tip3d_errors_mm


def test_tip3d_errors_skip_invalid_and_nan():
    p_true = np.zeros((4, 3))
    p_est = np.array([[0.001, 0, 0], [np.nan, 0, 0], [0, 0.002, 0], [0, 0, 0.5]])
    err = tip3d_errors_mm(p_est, p_true, np.array([1, 1, 1, 0], bool))
    assert err == pytest.approx([1.0, 2.0])


def test_rising_edges_debounce():
    f = np.array([0, 1, 1, 0, 1, 0, 0, 0, 0, 1, 1], bool)
    assert rising_edges(f).tolist() == [1, 4, 9]
    assert rising_edges(f, min_gap=3).tolist() == [1, 9]


def test_approaches_lead_time_and_error():
    t = np.arange(0, 1.0, 0.001)
    depth = np.where((t >= 0.5) & (t < 0.7), 0.001, -0.01)
    finger = np.tile([0.2, 0.0, -0.15], (t.size, 1))
    dev = np.tile([0.25, 0.0, -0.15], (t.size, 1))
    dev[t >= 0.3] = [0.2005, 0.0, -0.15]       # arrives 200 ms early, 0.5 mm off
    (a,) = approaches(t, depth, finger, dev)
    assert a.t_touch == pytest.approx(0.5)
    assert a.lead_time_s == pytest.approx(0.2, abs=1e-9)
    assert a.position_error_m == pytest.approx(0.0005)
    late = np.tile([0.25, 0.0, -0.15], (t.size, 1))
    late[t >= 0.55] = [0.2, 0.0, -0.15]
    (b,) = approaches(t, depth, finger, late)
    assert b.lead_time_s == pytest.approx(-0.05, abs=1e-9)
    never = np.tile([0.25, 0.0, -0.15], (t.size, 1))
    assert approaches(t, depth, finger, never)[0].lead_time_s is None


def test_linear_fit_and_force_depth():
    d = np.linspace(0, 0.004, 50)
    a, b, r2 = force_depth_r2(d, 800 * d + 0.01)
    assert a == pytest.approx(800) and r2 == pytest.approx(1.0)
    rng = np.random.default_rng(0)
    _, _, r2n = linear_fit(d, 800 * d + rng.normal(0, 0.5, d.size))
    assert r2n < 0.9
    assert np.isnan(linear_fit([1, 2], [1, 2])[2])


def test_reaction_misses_counts_ticks_that_tracked_a_bad_record():
    """Computed from the logged records, not by the guard: a guard that tracked a NaN, uncalibrated,
    stale or unconfident record (or one the log never saw) is caught."""
    from vishap.apps.summary import reaction_misses

    meta = {"config": {"stale_after_s": 0.15}}
    scene = {"seq": np.array([1, 2, 3, 4]), "X_d": np.array([[0.2, 0, -0.15], [np.nan, 0, -0.15], [0.2, 0, -0.15], [0.2, 0, -0.15]]),
             "calibrated": np.array([True, True, False, True]), "t_sample": np.array([0.0, 0.1, 0.2, 0.3]),
             "confidence": np.array([0.9, 0.9, 0.9, 0.1])}
    t = np.array([0.01, 0.11, 0.21, 0.31, 0.50, 0.51])
    servo = {"t": t, "record_seq": np.array([1, 2, 3, 4, 1, 9]), "guard": np.zeros(6, int)}
    # tracked: fine, NaN, uncalibrated, unconfident, 0.5 s stale, unknown record
    assert reaction_misses(meta, {"scene": scene, "servo": servo}) == 5
    servo["guard"] = np.array([0, 1, 2, 1, 1, 2])  # the guard held or retreated on every bad one
    assert reaction_misses(meta, {"scene": scene, "servo": servo}) == 0
