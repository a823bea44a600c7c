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


def test_a_finger_vision_reports_lost_is_held_on_the_very_next_tick():
    g = guard()
    good = g.decide(0.999, [0.25, 0.01, -0.12], made_at=0.999, confidence=1.0)
    # the tracker still trusts its coasting prediction (confidence 0.6 after one miss), but the frame
    # gave no fingertip: hold now, not ~4 frames later when the confidence has decayed
    d = g.decide(1.0, [0.27, 0.02, -0.11], made_at=1.0, confidence=0.6, lost=True)
    assert d.action == "hold" and d.fault is Fault.FINGER_LOST
    np.testing.assert_array_equal(d.X_d, good.X_d)
    assert g.decide(1.3001, [0.27, 0.02, -0.11], made_at=1.3, confidence=0.6, lost=True).action == "retreat"
    # a stalled vision process is not hidden by a lost finger: it keeps its timer while pressed
    g = guard()
    g.decide(0.0, [0.25, 0.01, -0.12], made_at=0.0, confidence=1.0)
    d = g.decide(0.2, [0.25, 0.01, -0.12], made_at=0.0, confidence=0.6, lost=True, pressed=True)
    assert d.fault is Fault.VISION_STALLED
    # an unstamped input is a NaN fault, whatever else it says
    assert g.decide(0.201, [0.25, 0.01, -0.12], made_at=np.nan, confidence=1.0, lost=True).fault is Fault.NAN_INPUT


def test_a_corrupt_record_is_a_counted_fault_that_holds_then_retreats():
    g = guard()
    good = g.decide(0.999, [0.25, 0.01, -0.12], made_at=0.999, confidence=1.0)
    for t in np.arange(1.0, 1.3, 0.001):  # the record's content says "fine", but it is not a record
        d = g.decide(float(t), [0.2, 0.0, -0.1], made_at=float(t), confidence=1.0, valid=False)
        assert d.action == "hold" and d.fault is Fault.BAD_RECORD
        np.testing.assert_array_equal(d.X_d, good.X_d)
    assert g.decide(1.301, [0.2, 0.0, -0.1], made_at=1.301, confidence=1.0, valid=False).action == "retreat"
    assert g.counts["bad_record"] == 1


@pytest.mark.parametrize("seq, flags, subject, n, ok", [
    (1.0, (0.0, 1.0), -1.0, 3, True), (7.0, (1.0,), 2.0, 3, True), (2.0**40, (0.0,), 0.0, None, True),
    (0.0, (0.0,), -1.0, 3, False),  # an all-zero record: the scene step counts from 1
    (np.nan, (0.0,), 0.0, 3, False), (np.inf, (0.0,), 0.0, 3, False), (1.5, (0.0,), 0.0, 3, False),
    (-3.0, (0.0,), 0.0, 3, False), (1.0, (0.5,), 0.0, 3, False), (1.0, (np.nan,), 0.0, 3, False),
    (1.0, (1.0,), 3.0, 3, False), (1.0, (1.0,), -2.0, 3, False), (1.0, (1.0,), np.nan, None, False),
    (1.0, (1.0,), 0.5, 3, False),
])
def test_record_values_valid(seq, flags, subject, n, ok):
    from vishap.runtime.safety import record_values_valid

    assert record_values_valid(seq, flags, subject, n) is ok


def test_vision_losing_the_finger_reaches_the_guard_in_the_record_and_holds_on_the_next_tick():
    """Scene step → record → servo step: the frame in which vision's tracker drops the track makes the
    next servo tick hold, while the world's predictor still offers a coasting target."""
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device
    from vishap.runtime.core import SceneStep
    from vishap.world.scene import load_scene
    from vishap.world.world import World

    scene = load_scene("wall")
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco())
    step = make_servo_step(dev, scene)
    scene_step = SceneStep(World(scene), np.eye(4), tip_radius_m=0.008, mount_offset=step.mount)
    dev.reset(kinematics.ik(np.array([0.2, 0.0, -0.1])))
    t, rec = 0.0, None
    for k in range(10):  # a finger above the wall, moving slowly, seen at 30 Hz
        t_frame = k / 30.0
        p_cam = np.array([0.2 + 0.01 * t_frame, 0.0, -0.10])
        rec, _, _ = scene_step.step(t_frame, True, p_cam, 1.0, None)
        while t < t_frame + 1 / 30.0 - 1e-9:
            tk = step.tick(t, rec)
            t += 1e-3
    assert tk.action == "track"
    # one missed frame while the tracker still coasts (confidence 0.6): not lost, the device follows
    rec, inter, _ = scene_step.step(10 / 30.0, False, np.full(3, np.nan), 0.6, None)
    assert inter is not None and np.all(np.isfinite(rec.X_ee)) and not rec.lost  # the world still predicts
    assert step.tick(t, rec).action == "track"
    # the tracker drops the track (confidence 0): the record says lost and the very next tick holds
    rec, inter, _ = scene_step.step(11 / 30.0, False, np.full(3, np.nan), 0.0, None)
    assert inter is not None and np.all(np.isfinite(rec.X_ee)) and rec.lost
    tk = step.tick(11 / 30.0 + 1e-3, rec)
    assert tk.action == "hold" and tk.fault.value == "finger_lost"
