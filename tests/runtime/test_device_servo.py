import numpy as np

from vishap.runtime.device_servo import ACTIONS, FAULTS, make_sim_device_servo, target_record


def run(servo, t0, t1, record):
    out = None
    for k in range(int(round(t0 * 1000)), int(round(t1 * 1000))):
        t = k * 1e-3
        rec = record(t) if callable(record) else record
        out = servo.step(t, rec).copy()
        F = servo.loop.controller.F_cmd
        assert np.all(np.isfinite(F))
        assert np.linalg.norm(F) <= servo.loop.device.limits.peak_force_n + 1e-9
    return out


def test_tracks_a_fresh_target():
    s = make_sim_device_servo()
    goal = [0.22, 0.02, -0.12]
    out = run(s, 0.001, 1.5, lambda t: target_record(goal, t, 1.0))
    assert ACTIONS[int(out[4])] == "track"
    np.testing.assert_allclose(out[1:4], goal, atol=1e-3)


def test_nan_target_holds_within_one_cycle_and_is_counted():
    s = make_sim_device_servo()
    goal = [0.22, 0.02, -0.12]
    run(s, 0.001, 1.0, lambda t: target_record(goal, t, 1.0))
    out = s.step(1.0, np.array([np.nan, 0.0, -0.1, 1.0, 1.0, 1.0])).copy()
    assert ACTIONS[int(out[4])] == "hold"
    assert FAULTS[int(out[5]) - 1] == "nan_input"
    out = run(s, 1.001, 1.2, np.array([np.nan, 0.0, -0.1, 1.0, 1.0, 1.0]))
    np.testing.assert_allclose(out[1:4], goal, atol=1.5e-3)
    assert s.guard.counts["nan_input"] == 1


def test_missing_calibration_retreats():
    s = make_sim_device_servo()
    out = run(s, 0.001, 1.5, lambda t: target_record([0.22, 0.0, -0.15], t, 1.0, calibrated=False))
    assert ACTIONS[int(out[4])] == "retreat"
    np.testing.assert_allclose(out[1:4], [0.20, 0.0, -0.05], atol=2e-3)
