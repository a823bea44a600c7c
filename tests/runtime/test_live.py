import functools
import time

import numpy as np

from vishap.runtime.live import LiveServo


class PointMassServo:
    """A 1-D point mass under PD control towards the target: a real (tiny) servo workload."""

    def __init__(self, kp: float, kv: float):
        self.kp, self.kv = kp, kv
        self.x = 0.0
        self.v = 0.0

    def step(self, t, target):
        goal = 0.0 if target is None else target[0]  # None: nothing written yet
        f = self.kp * (goal - self.x) - self.kv * self.v
        self.v += f * 1e-3
        self.x += self.v * 1e-3
        return np.array([t, self.x, self.v])


def make_point_mass(kp=400.0, kv=40.0):
    return PointMassServo(kp, kv)


def test_live_servo_follows_targets_and_reports_lateness():
    servo = LiveServo(functools.partial(make_point_mass), target_size=1, state_size=3)
    servo.start()
    try:
        servo.write_target([0.05])
        deadline = time.monotonic() + 5.0
        x = 0.0
        while time.monotonic() < deadline:
            state, seq = servo.read_state()
            x = state[1]
            if seq > 600 and abs(x - 0.05) < 1e-3:
                break
            time.sleep(0.01)
        assert abs(x - 0.05) < 1e-3, f"servo did not settle: x={x}"
    finally:
        report = servo.stop()
    assert report.steps > 500
    assert report.lateness["ticks"] == report.steps
    # what the process obtained is reported consistently: FIFO at the asked priority, or why not
    assert report.sched_fifo == report.realtime.startswith("SCHED_FIFO priority 80")
    if not report.sched_fifo:
        assert "best-effort" in report.realtime
    assert np.isfinite(report.step_us_median) and report.step_us_median > 0


def test_live_servo_clock_read_from_the_parent_matches_the_servo_time():
    """LiveServo.now() is the servo's simulated time: equal to the time the servo stamps its state with
    (within a few periods), and strictly increasing however stale the state mailbox is."""
    servo = LiveServo(functools.partial(make_point_mass), target_size=1, state_size=3, realtime=False)
    servo.start()
    try:
        time.sleep(0.2)
        gaps, nows = [], []
        for _ in range(20):
            state, _ = servo.read_state()
            now = servo.now()
            gaps.append(now - state[0])
            nows.append(now)
            time.sleep(0.005)
    finally:
        servo.stop()
    assert np.all(np.diff(nows) > 0)
    # the state is at most a few periods old on an idle machine; a loaded one may delay the servo's
    # write, never make the state newer than the servo's clock
    assert np.median(gaps) < 0.02 and min(gaps) > -0.0015, gaps


class Witness:
    """Reports what the servo process hands it: 1 while nothing was written, then the first value."""

    def step(self, t, target):
        return np.array([t, 1.0 if target is None else 0.0, np.nan if target is None else target[0]])


def test_the_servo_object_gets_none_until_the_first_write_then_what_was_written():
    """An all-zero record must not read as "nothing yet": the mailbox's own sequence number decides."""
    servo = LiveServo(Witness, target_size=2, state_size=3, realtime=False)
    servo.start()
    try:
        deadline = time.monotonic() + 5.0
        while (state := servo.read_state())[1] < 20 and time.monotonic() < deadline:
            time.sleep(0.005)
        assert state[1] >= 20 and state[0][1] == 1.0  # nothing written: None, not zeros
        servo.write_target([0.0, 0.0])  # a record of zeros, written
        while time.monotonic() < deadline:
            state, _ = servo.read_state()
            if state[1] == 0.0:
                break
            time.sleep(0.005)
        assert state[1] == 0.0 and state[2] == 0.0
    finally:
        servo.stop()


def _live_cycle():
    from vishap.apps.config import DemoConfig
    from vishap.apps.live_loop import LiveCycle

    return LiveCycle(DemoConfig(scene="wall").model_dump(), "sim", None)


def test_an_all_zero_or_corrupt_record_is_a_fault_held_then_retreated_not_nothing_yet():
    from vishap.runtime.core import GUARD_CODES, RECORD_SIZE, TargetRecord

    cyc = _live_cycle()
    guard = cyc.cycle.step.guard
    for k in range(50):  # nothing written yet: the arm is held where it is, no fault
        state = cyc.step(k * 1e-3, None)
    assert state[4] == GUARD_CODES["idle"] and sum(guard.counts.values()) == 0
    zeros = np.zeros(RECORD_SIZE + 1)
    codes = [cyc.step(k * 1e-3, zeros)[4] for k in range(50, 50 + 650)]
    assert codes[0] == GUARD_CODES["hold"]  # the first tick that sees it
    assert guard.counts["bad_record"] == 1  # one episode, counted once
    assert codes[-1] == GUARD_CODES["retreat"]  # after retreat_after_s (0.5 s)
    assert GUARD_CODES["track"] not in codes and GUARD_CODES["idle"] not in codes
    # a good record recovers; a NaN counter, a flag of 0.5, a subject beyond the scene never crash the servo
    good = TargetRecord(1, (0.20, 0.0, -0.13), 0.7, 1.0, True, True, 0, False, False).pack()
    assert cyc.step(0.7, np.append(good, np.nan))[4] == GUARD_CODES["track"]
    for i, bad in ((0, np.nan), (0, 1e300), (6, 0.5), (8, 7.0), (8, np.inf)):
        rec = np.append(good, np.nan)
        rec[0] += 1
        rec[i] = bad
        state = cyc.step(0.701, rec)
        assert state[4] == GUARD_CODES["hold"] and np.all(np.isfinite(state)), (i, bad)
        good[0] += 2
        assert cyc.step(0.702, np.append(good, np.nan))[4] == GUARD_CODES["track"]
    assert guard.counts["bad_record"] == 6
