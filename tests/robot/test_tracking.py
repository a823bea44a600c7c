"""Tracking helpers: step metrics on known signals; default gains are critically damped; gap policies."""
import argparse

import numpy as np
import pytest

from vishap.robot.controller import Gains
from vishap.robot.params import DEFAULT
from vishap.robot.tracking import moving_target, step_metrics, step_response


def test_step_metrics_on_a_known_second_order_response():
    t = np.arange(0, 2.0, 1e-3)
    wn, zeta = 20.0, 0.5
    wd = wn * np.sqrt(1 - zeta**2)
    tt = np.clip(t - 0.1, 0, None)
    y = 1 - np.exp(-zeta * wn * tt) * (np.cos(wd * tt) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * tt))
    m = step_metrics(t, y, 0.1, 1.0)
    assert m["overshoot_pct"] == pytest.approx(100 * np.exp(-np.pi * zeta / np.sqrt(1 - zeta**2)), rel=1e-3)
    assert m["settling_time_s"] == pytest.approx(4 / (zeta * wn), rel=0.25)
    assert m["steady_state_error_m"] < 1e-6


def test_default_gains_do_not_overshoot():
    import itertools

    from vishap.robot import kinematics as kin
    from vishap.robot.tracking import CENTRE

    f = np.array(DEFAULT.joint_friction_nm)
    for d in np.eye(3):
        r = step_response(Gains(), d, 0.02, duration_s=0.6)
        # Coulomb friction holds the tip wherever each joint's share of Kp·e stays under its friction
        # torque: a dead band whose reach along d is the largest d-component of J⁻ᵀ·(±f1, ±f2, ±f3),
        # over Kp (0.040 / 0.045 / 0.054 N along x / y / z at the step's end: 50-67 µm); 5 % more, as
        # the z step ends sliding slowly onto that edge (68.0 µm over the last 0.1 s, 67.3 at its end)
        Jit = np.linalg.inv(kin.jacobian(kin.ik(CENTRE + 0.01 * d)).T)
        reach = max(abs(Jit @ (np.array(s) * f) @ d) for s in itertools.product((-1.0, 1.0), repeat=3))
        dead_band = 1.05 * reach / Gains().kp
        assert r["overshoot_pct"] < 1.0 and r["steady_state_error_m"] < dead_band and r["settling_time_s"] < 0.3


def test_extrapolation_beats_hold_on_a_moving_finger():
    hold = moving_target(Gains(), "hold", 30.0, latency_s=0.03, duration_s=1.5)
    extra = moving_target(Gains(), "extrapolate", 30.0, latency_s=0.03, duration_s=1.5)
    assert extra["rms_error_m"] < 0.5 * hold["rms_error_m"]


def test_bench_tracking_quick(tmp_path):
    from vishap.bench import tracking

    rec = tracking.run(argparse.Namespace(out=str(tmp_path), gains=None, latency_ms=30.0, duration=1.0, quick=True))
    assert set(rec["responses"]) == {"step_x", "step_y", "step_z", "step_z_no_gravity_comp", "ramp_x"}
    assert len(rec["policies"]) == 3
    for name in ("tracking_steps.png", "tracking_policies.png"):
        assert (tmp_path / name).stat().st_size > 1000


def test_a_run_shorter_than_its_settling_time_is_refused_by_name():
    from vishap._core.errors import ConfigError
    from vishap.robot.gains import Gains
    from vishap.robot.tracking import band_rms, hold_and_approach

    with pytest.raises(ConfigError) as exc:
        hold_and_approach(Gains(), "hold", seconds=0.5)
    assert exc.value.field == "seconds"
    assert band_rms(np.zeros((0, 3)), 1000.0) == 0.0


def test_band_rms_of_a_piece_of_a_move_is_its_buzz_not_the_jump_between_its_ends():
    """156 ms of an approach: the force moves smoothly from −0.6 to +0.7 N (nothing above 30 Hz)
    with 0.05 N of 55 Hz buzz on it. The plain FFT took the 1.3 N jump between the ends for a
    sawtooth and read 0.14 N above 30 Hz; the buzz alone is 0.035 N."""
    from vishap.robot.tracking import band_rms

    t = np.arange(156) * 1e-3
    s = t / t[-1]
    move = -0.6 + 1.3 * (3 * s**2 - 2 * s**3)
    buzz = 0.05 * np.sin(2 * np.pi * 55 * t + 1.0)
    assert band_rms(move + buzz, 1000.0, 30.0) == pytest.approx(band_rms(buzz, 1000.0, 30.0), rel=0.01)
    assert band_rms(buzz, 1000.0, 30.0) == pytest.approx(0.05 / np.sqrt(2), rel=0.05)
    assert band_rms(move, 1000.0, 30.0) < 0.002
    # a straight trend (0.16 and 0.31 m over the piece) leaves under 1 % of itself above 30 Hz
    assert band_rms(np.c_[t, -2 * t, 0 * t + 3], 1000.0, 30.0) < 0.003
    assert band_rms(np.c_[move, buzz], 1000.0) ** 2 == pytest.approx(np.var(move) + np.var(buzz), rel=1e-9)  # Parseval
