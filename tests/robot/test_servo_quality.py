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
    # rel 2e-3, not exact: band_rms mirrors the record, and the kink where the record meets its
    # mirror image moves the band's share by 0.1 %
    assert band_rms(x, 1000.0, 30.0) == pytest.approx(0.1 / np.sqrt(2), rel=2e-3)
    assert band_rms(np.c_[x, x], 1000.0, 30.0) == pytest.approx(0.1, rel=2e-3)  # columns add in power


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
    assert 1.92 < r["device_speed_near_finger_max_t_s"] < 2.0  # within 20 mm of the finger from 1.925 s
    assert len(r["touches"]) == 1 and r["touches"][0]["makes_in_100ms"] == 3
    # Λ inferred from depth: free → engaged and back twice, then engaged (1 mm > engage_m)
    assert r["lambda_changes"] == 5 and r["lambda_changes_per_approach"] == [5]
    assert r["lambda_changes_per_touch_cycle"] == [5]  # the press never ends: the cycle runs to the end


def _write(tmp_path, servo, summary=None):
    np.savez(tmp_path / "log.npz", **{f"servo/{k}": v for k, v in servo.items()})
    (tmp_path / "summary.json").write_text(json.dumps(summary or {}))
    return tmp_path


def test_a_hold_needs_the_device_arrived_and_the_still_target_figure_stays_beside_it(tmp_path):
    """A still target the device is still travelling into (0.5 N of 10 Hz pull) is not a still hold;
    the device at rest on it with 50 Hz buzz is, and the target-only figure keeps both."""
    n = 1200
    t = np.arange(n) * 1e-3
    X = np.tile([0.2, 0.0, -0.12], (n, 1))
    p = X.copy()
    p[:500, 0] -= 0.02 * (1.0 - t[:500] / 0.5)  # 20 mm → 0 at 40 mm/s into the still target
    F = np.zeros((n, 3))
    F[:500, 0] = 0.5 * np.sin(2 * np.pi * 10 * t[:500])
    F[500:, 2] = 0.02 * np.sin(2 * np.pi * 50 * t[500:])
    far = np.tile([0.5, 0.0, 0.0], (n, 1))
    servo = {"t": t, "F_cmd": F, "saturated": np.zeros(n, bool), "in_contact": np.zeros(n, bool),
             "law_active": np.zeros(n, bool), "guard": np.zeros(n, int), "device_point": p, "finger_point": far,
             "device_depth": np.full(n, -0.01), "X_d": X}
    r = analyse(read_log(_write(tmp_path, servo)))
    assert r["hold_ripple_n_rms"] == pytest.approx(0.02 / np.sqrt(2), rel=0.05)
    assert r["hold_ripple_above_30hz_n_rms"] == pytest.approx(0.02 / np.sqrt(2), rel=0.05)
    assert r["hold_ticks"] < 700 < r["still_target_ticks"]
    assert r["still_target_ripple_n_rms"] > 0.2  # the travelling part dominates the target-only figure


def test_ready_touches_use_the_world_bench_conditions(tmp_path):
    """Two touches on the wall's plate: the first on a device waiting still on the surface (ready),
    the second on a device still sinking at 50 mm/s along the normal (not: still_normal fails)."""
    from vishap.bench.servo_quality import ready_touches
    from vishap.world.scene import load_scene

    obj = load_scene("wall").objects[0]
    nrm = np.asarray(obj.normal, float)
    n = 3000
    t = np.arange(n) * 1e-3
    c = np.asarray(obj.centre, float)
    p = np.tile(c, (n, 1))
    p[1900:2000] += np.outer(0.05 * (2.0 - t[1900:2000]), nrm)  # 5 mm → 0 at 50 mm/s before the 2nd touch
    h = np.full(n, 0.01)  # the finger's height over the surface
    h[700:1000] = np.linspace(0.01, 0.0, 300)
    h[1000:1300] = 0.0
    h[1300:1500] = np.linspace(0.0, 0.01, 200)
    h[1700:2000] = np.linspace(0.01, 0.0, 300)
    h[2000:2300] = 0.0
    pf = c + np.outer(h, nrm)
    contact = h <= 0.0
    servo = {"t": t, "F_cmd": np.zeros((n, 3)), "saturated": np.zeros(n, bool), "in_contact": contact,
             "law_active": contact, "guard": np.zeros(n, int), "device_point": p, "finger_point": pf,
             "device_depth": -(p - c) @ nrm, "finger_depth": -h, "X_d": p}
    rt = ready_touches(read_log(_write(tmp_path, servo)), "wall")
    assert [round(x["t_s"], 3) for x in rt] == [0.999, 1.999]  # the finger reaches the surface
    assert rt[0]["ready"] and all(rt[0]["checks"].values())
    assert not rt[1]["ready"] and rt[1]["checks"] == {"still_normal": False, "still_tangential": True, "face": True,
                                                      "inside": True}
    # the finger landing 8 mm off the face's centre: 12 mm inside the wall's 40 mm plate, 7 mm inside
    # the button's 30 mm keycap (each scene's passive face from its scene file)
    off = dict(servo, finger_point=pf + 0.008 * np.asarray(obj.R, float)[:, 0])
    assert ready_touches(read_log(_write(tmp_path, off)), "wall")[0]["checks"]["inside"] is True
    assert ready_touches(read_log(_write(tmp_path, off)), "button")[0]["checks"]["inside"] is False


def test_the_readiness_option_reads_wall_button_and_fabric_over_seeds_0_to_9(tmp_path):
    from types import SimpleNamespace

    from vishap._core.errors import ConfigError
    from vishap.bench.servo_quality import _demo_folders

    for scene in ("wall", "button", "fabric"):
        for seed in range(10):
            (tmp_path / f"{scene}_{seed}").mkdir()
            (tmp_path / f"{scene}_{seed}" / "summary.json").write_text("{}")
    args = SimpleNamespace(seeds="0", scenes="wall", substeps=10, logs=str(tmp_path), readiness=True, workers=1,
                           address=None)
    got = _demo_folders(args, tmp_path / "out")
    assert [(s, k) for s, k, _ in got] == [(s, k) for s in ("wall", "button", "fabric") for k in range(10)]
    args.readiness, args.scenes = False, "wall,table"
    with pytest.raises(ConfigError, match="--scenes"):
        _demo_folders(args, tmp_path / "out")


def test_the_chart_draws_from_analysed_logs(tmp_path):
    from vishap.bench.servo_quality import chart, ready_touches

    log = read_log(_log(tmp_path))
    rec = analyse(log)
    rec.update(scene="wall", seed=0, ready_touches=ready_touches({**log, "finger_depth": -log["device_depth"]}, "wall"))
    alone = {k: {"hold_ripple_n_rms": 0.02, "hold_ripple_above_30hz_n_rms": 0.02, "approach_ripple_above_30hz_n_rms": 0.03,
                 "tip_vibration_above_30hz_um_rms": 0.6} for k in ("before", "shipped")}
    png = chart([rec], alone, tmp_path)
    assert png.is_file() and png.stat().st_size > 10_000
    assert len(rec["ready_touches"]) == 1  # the log's one touch, judged by device_ready


def test_the_record_names_the_demo_and_moment_of_the_fastest_device_near_the_finger(tmp_path):
    from vishap.bench.servo_quality import _worst_near

    rec = analyse(read_log(_log(tmp_path)))
    slow = {"scene": "button", "seed": 3, "device_speed_near_finger_max_m_s": 0.1, "device_speed_near_finger_max_t_s": 0.5}
    got = _worst_near([slow, {**rec, "scene": "wall", "seed": 1}])
    assert got == {"scene": "wall", "seed": 1, "t_s": rec["device_speed_near_finger_max_t_s"],
                   "m_s": rec["device_speed_near_finger_max_m_s"]}
    assert _worst_near([]) is None
