import numpy as np
import pytest

from vishap.runtime.safety import Fault, TargetGuard

LO, HI = np.array([0.10, -0.065, -0.20]), np.array([0.30, 0.065, -0.04])
HOME = np.array([0.2, 0.0, -0.06])


def guard():
    return TargetGuard(LO, HI, HOME, stale_after_s=0.1, retreat_after_s=0.3)


def test_fresh_input_is_tracked_and_clamped():
    g = guard()
    d = g.decide(0.0, [0.2, 0.5, -0.1], made_at=0.0, confidence=1.0)
    assert d.action == "track" and d.fault is None
    np.testing.assert_allclose(d.X_d, [0.2, 0.065, -0.1])


@pytest.mark.parametrize(
    "kwargs, fault",
    [
        (dict(X_d=[np.nan, 0, -0.1], made_at=1.0, confidence=1.0), Fault.NAN_INPUT),
        (dict(X_d=[0.2, 0, -0.1], made_at=0.0, confidence=1.0), Fault.VISION_STALLED),
        (dict(X_d=[0.2, 0, -0.1], made_at=1.0, confidence=0.0), Fault.FINGER_LOST),
    ],
)
def test_each_fault_holds_at_once_then_retreats(kwargs, fault):
    g = guard()
    good = g.decide(0.999, [0.25, 0.01, -0.12], made_at=0.999, confidence=1.0)
    d = g.decide(1.0, **kwargs)  # the very next servo tick
    assert d.action == "hold" and d.fault is fault
    np.testing.assert_array_equal(d.X_d, good.X_d)
    assert np.all(np.isfinite(d.X_d))
    for t in np.arange(1.001, 1.3, 0.001):
        g.decide(float(t), **kwargs)
    d = g.decide(1.31, **kwargs)
    assert d.action == "retreat"
    np.testing.assert_array_equal(d.X_d, HOME)
    assert g.counts[fault.value] == 1  # one episode, counted once


def test_missing_calibration_retreats_immediately():
    g = guard()
    d = g.decide(0.0, [0.2, 0, -0.1], made_at=0.0, confidence=1.0, calibrated=False)
    assert d.action == "retreat" and d.fault is Fault.CALIBRATION_MISSING


def test_recovery_returns_to_tracking_and_counts_episodes():
    g = guard()
    g.decide(0.0, [0.2, 0, -0.1], made_at=0.0, confidence=0.0)
    g.decide(0.001, [0.2, 0, -0.1], made_at=0.001, confidence=1.0)
    g.decide(0.002, [0.2, 0, -0.1], made_at=0.002, confidence=0.0)
    assert g.counts["finger_lost"] == 2
    g.count(Fault.FRAME_DROPPED)
    assert g.counts["frame_dropped"] == 1


def test_a_target_stamped_in_the_future_is_held_not_tracked():
    g = guard()
    good = g.decide(1.0, [0.1, 0.0, 0.0], made_at=1.0, confidence=0.9)
    assert good.action == "track"
    d = g.decide(1.001, [0.12, 0.0, 0.0], made_at=2.0, confidence=0.9)  # a clock fault
    assert d.action == "hold" and d.fault is Fault.FUTURE_STAMP
    assert np.allclose(d.X_d, good.X_d) and g.counts["future_stamp"] == 1


@pytest.mark.parametrize("field, value", [("retreat_point", (np.nan, 0.0, 0.0)), ("retreat_point", (0.2, 0.0, -np.inf)),
                                          ("box_hi", (np.inf, 0.1, 0.1)),
                                          ("stale_after_s", np.nan), ("retreat_after_s", np.inf),
                                          ("min_confidence", np.nan), ("min_confidence", 1.5)])
def test_non_finite_or_out_of_range_settings_are_refused_by_name(field, value):
    from vishap._core.errors import ConfigError

    kw = {"box_lo": LO, "box_hi": HI, "retreat_point": HOME, field: value}
    with pytest.raises(ConfigError) as exc:
        TargetGuard(**kw)
    assert exc.value.field in (field, "box")


def test_a_finger_lost_while_it_presses_the_device_is_held_until_it_lets_go():
    g = guard()
    g.decide(0.999, [0.25, 0.01, -0.12], made_at=0.999, confidence=1.0)
    lost = dict(X_d=[0.2, 0, -0.1], confidence=0.0)
    for t in np.arange(1.0, 2.0, 0.001):  # vision blind for 1 s, the device pushed in all along
        d = g.decide(float(t), made_at=float(t), pressed=True, **lost)
        assert d.action == "hold" and d.fault is Fault.FINGER_LOST
    for t in np.arange(2.0, 2.299, 0.001):  # let go: the retreat timer starts now
        assert g.decide(float(t), made_at=float(t), pressed=False, **lost).action == "hold"
    assert g.decide(2.301, made_at=2.301, pressed=False, **lost).action == "retreat"
    # a stalled vision process is a fault of the system: it retreats even while pressed
    g = guard()
    g.decide(0.0, [0.25, 0.01, -0.12], made_at=0.0, confidence=1.0)
    for t in np.arange(0.001, 0.45, 0.001):
        d = g.decide(float(t), [0.25, 0.01, -0.12], made_at=0.0, confidence=1.0, pressed=True)
    assert d.action == "retreat" and d.fault is Fault.VISION_STALLED
