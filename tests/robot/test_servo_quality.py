"""The servo-quality measures on logs whose answers are known, and the band RMS they rest on."""
import json

import numpy as np
import pytest

from vishap.bench.servo_quality import analyse, read_log
from vishap.robot.tracking import band_rms


def test_band_rms_splits_a_signal_at_the_frequency():
    t = np.arange(2000) * 1e-3
    x = 0.3 * np.sin(2 * np.pi * 10 * t) + 0.1 * np.sin(2 * np.pi * 100 * t)
    assert band_rms(x, 1000.0) == pytest.approx(np.sqrt(0.3**2 + 0.1**2) / np.sqrt(2), rel=1e-6)
    assert band_rms(x, 1000.0, 30.0) == pytest.approx(0.1 / np.sqrt(2), rel=1e-6)
    assert band_rms(np.c_[x, x], 1000.0, 30.0) == pytest.approx(0.1, rel=1e-6)  # columns add in power


def _log(tmp_path):
    """3 s at 1 kHz: a still hold with 50 Hz buzz, an approach at 0.2 m/s, a chattering touch-down."""
    n = 3000
    t = np.arange(n) * 1e-3
    F = np.zeros((n, 3))
    F[:1000, 2] = 0.05 * np.sin(2 * np.pi * 50 * t[:1000])  # hold: 0.035 N rms, all above 30 Hz
    X = np.tile([0.2, 0.0, -0.12], (n, 1)).astype(float)
    p = X.copy()
    p[1000:2000, 0] += 0.2 * (t[1000:2000] - 1.0)  # approach at 0.2 m/s toward the finger
    p[2000:, 0] = p[1999, 0]
    X[1000:, 0] = p[1000:, 0]
    finger = np.tile([0.2 + 0.2 + 0.005, 0.0, -0.12], (n, 1))
    contact = np.zeros(n, bool)
    contact[2000:2010] = True
    contact[2020:2030] = True  # a break and a second make within 100 ms
    contact[2050:] = True
    sat = np.zeros(n, bool)
    sat[1500] = True  # outside contact
    F[1500, 0] = 2.0  # a 2 N step out and back
    depth = np.where(contact, 0.001, -0.002)
    law = contact.copy()
    servo = {"t": t, "F_cmd": F, "saturated": sat, "in_contact": contact, "law_active": law,
             "guard": np.zeros(n, int), "device_point": p, "finger_point": finger, "device_depth": depth, "X_d": X}
    np.savez(tmp_path / "log.npz", **{f"servo/{k}": v for k, v in servo.items()})
    (tmp_path / "summary.json").write_text(json.dumps({"force_depth_r2": 0.99}))
    return tmp_path


def test_the_measures_find_what_the_log_holds(tmp_path):
    r = analyse(read_log(_log(tmp_path)))
    assert r["saturated_ticks_outside_contact"] == 1
    assert r["max_force_step_outside_contact_n"] == pytest.approx(2.0)
    assert r["hold_ripple_above_30hz_n_rms"] == pytest.approx(0.05 / np.sqrt(2), rel=0.05)
    assert r["device_speed_near_finger_max_m_s"] == pytest.approx(0.2, rel=0.02)
    assert len(r["touches"]) == 1 and r["touches"][0]["makes_in_100ms"] == 3
    # Λ inferred from depth: free → engaged and back twice, then engaged (1 mm > engage_m)
    assert r["lambda_changes"] == 5 and r["lambda_changes_per_approach"] == [5]
