import math

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.robot.build import build_servo
from vishap.robot.travel import TravelLimiter


def _run(lim, target, v_target=(0.0, 0.0, 0.0), seconds=0.5, dt=1e-3, start=(0.0, 0.0, 0.0)):
    lim.reset(*start)
    xs, vs = [], []
    for k in range(int(seconds / dt) + 1):
        t = k * dt
        tx = np.asarray(target, float) + np.asarray(v_target, float) * t
        out = lim.step(t, *tx, *v_target)
        xs.append(out[:3])
        vs.append(out[3:])
    return np.array(xs), np.array(vs), dt


def test_a_jump_is_travelled_within_the_speed_and_acceleration_limits_without_overshoot():
    lim = TravelLimiter(0.5, 10.0)
    xs, vs, dt = _run(lim, (0.03, 0.0, -0.02))
    speed = np.linalg.norm(vs, axis=1)
    accel = np.linalg.norm(np.diff(vs, axis=0), axis=1) / dt
    assert speed.max() <= 0.5 + 1e-9 and accel.max() <= 10.0 + 1e-6
    goal = np.array([0.03, 0.0, -0.02])
    dist = np.linalg.norm(xs - goal, axis=1)
    assert dist[-1] < 1e-6
    # straight and without overshoot: the remaining distance never grows along the way
    assert np.all(np.diff(dist) <= 1e-9)
    # about as fast as the limits allow: 36 mm at 10 m/s², peak 0.5 m/s → ≈ 0.12 s (bang-bang 0.12 s)
    t_arrive = dt * np.argmax(dist < 1e-4)
    assert t_arrive < 0.16


def test_a_moving_target_is_followed_without_lag_once_caught():
    lim = TravelLimiter(0.6, 20.0)
    xs, vs, dt = _run(lim, (0.01, 0.0, 0.0), v_target=(0.1, 0.05, 0.0), seconds=0.6)
    t = np.arange(len(xs)) * dt
    truth = np.array([0.01, 0.0, 0.0]) + np.outer(t, [0.1, 0.05, 0.0])
    assert np.abs(xs[-100:] - truth[-100:]).max() < 1e-6
    assert np.allclose(vs[-1], [0.1, 0.05, 0.0], atol=1e-6)


def test_bad_limits_are_refused_with_the_field_named():
    with pytest.raises(ConfigError, match="travel.max_accel_m_s2"):
        TravelLimiter(0.5, -1.0)
    with pytest.raises(ConfigError, match="travel.max_speed_m_s"):
        TravelLimiter(math.nan, 10.0)
    with pytest.raises(ConfigError, match="travel.max_jerk_m_s3"):
        TravelLimiter(0.5, 10.0, 0.0)


def _move(travel, dy: float, *, heat: float = 0.0, ticks: int = 600):
    """Settle the arm (past the 0.5 s force ramp-up), set the heating estimate, jump the target by
    ``dy`` along y; (peak |F_pd|, time to within 1 mm or None, ticks clipped at the peak).

    The controller's vision-rate boxcar is off: it would smooth the jump itself (over 33 ms), and
    these tests are about what the travel limiter does on its own."""
    from vishap.robot.gains import load_gains

    servo = build_servo(policy="hold", travel=travel, gains=load_gains(override={"vision_hz": 0.0})[0])
    ctrl = servo.controller
    for k in range(700):
        servo.tick(k * 1e-3)
    ctrl.heat = heat
    goal = np.array(ctrl.p) + np.array([0.0, dy, 0.0])
    peak, t_in = 0.0, None
    for k in range(700, 700 + ticks):
        servo.tick(k * 1e-3, goal)
        peak = max(peak, float(np.linalg.norm(ctrl.F_pd)))
        if t_in is None and np.linalg.norm(np.array(ctrl.p) - goal) < 1e-3:
            t_in = (k - 700) * 1e-3
    return peak, t_in, ctrl.n_saturated


def test_the_servo_with_travel_limits_moves_the_arm_without_saturating():
    """A 25 mm target jump: unlimited, the PD asks for more than the peak force and clips; limited,
    the arm gets there with a fraction of it and arrives within the limits' time."""
    free = _move(None, 0.025)
    limited = _move(TravelLimiter(0.6, 20.0), 0.025)
    assert free[2] > 0 and limited[2] == 0
    assert limited[0] < 0.5 * free[0]
    assert limited[1] is not None and limited[1] < 0.2


def test_hot_motors_slow_the_travel_instead_of_spending_the_contact_budget():
    """With the heating estimate near the continuous limit the acceleration limit shrinks (to 10 %
    at the least): the same move needs a fraction of the force and still arrives."""
    servo = build_servo()
    servo.controller.heat = 1.9
    assert servo.controller.thermal_headroom == pytest.approx(1.0 - 1.9 / 1.4**2)
    cold = _move(TravelLimiter(0.6, 40.0), 0.02, ticks=1000)
    hot = _move(TravelLimiter(0.6, 40.0), 0.02, heat=1.9, ticks=1000)
    assert hot[0] < 0.4 * cold[0]
    assert cold[1] < hot[1] < 0.6


def test_a_nan_target_does_not_poison_the_limiter():
    """A NaN target is refused before the shaper (no sample); the next finite target is followed as without limits."""
    servo = build_servo(travel=TravelLimiter())
    ctrl = servo.controller
    for k in range(700):
        servo.tick(k * 1e-3)
    goal = np.array(ctrl.p) + np.array([0.0, 0.01, 0.0])
    servo.tick(0.7, [math.nan] * 3)
    for k in range(701, 1300):
        servo.tick(k * 1e-3, goal)
    assert servo.shaper.n_rejected == 1 and ctrl.n_rejected == 0
    assert np.linalg.norm(np.array(ctrl.p) - goal) < 1e-4


def test_the_output_is_never_faster_than_max_speed_even_with_a_fast_target():
    lim = TravelLimiter(0.3, 40.0)
    xs, vs, dt = _run(lim, (0.05, 0.0, 0.0), v_target=(0.5, 0.2, 0.0), seconds=0.4)
    assert np.linalg.norm(vs, axis=1).max() <= 0.3 + 1e-12
    # and the position really moves at that speed: the output's steps match its velocity
    assert np.linalg.norm(np.diff(xs, axis=0), axis=1).max() / dt <= 0.3 + 1e-9


def test_near_the_finger_the_speed_is_capped_and_touch_down_is_slow():
    lim = TravelLimiter(0.6, 40.0)
    lim.reset(0.0, 0.0, 0.0)
    finger = np.array([0.05, 0.0, 0.0])
    speeds, dists = [], []
    for k in range(400):
        d = float(np.linalg.norm(finger - lim._x))
        out = lim.step(k * 1e-3, *finger, 0.0, 0.0, 0.0, finger_m=d)
        speeds.append(np.linalg.norm(out[3:]))
        dists.append(d)
    speeds, dists = np.array(speeds), np.array(dists)
    near = dists < 0.020
    assert near.any() and speeds[near].max() <= lim.near_speed + 1e-9 and lim.near_speed <= 0.25
    assert speeds.max() > 0.4  # far from the finger it still travels fast
    at_touch = dists < 0.001
    assert at_touch.any() and speeds[at_touch].max() <= 0.010 + 1e-12
    assert lim.cap_at(None) == 0.6 and lim.cap_at(0.0) == pytest.approx(lim.near_speed) and lim.cap_at(2 * lim.near_m + lim.margin_m) == 0.6
    assert lim.normal_cap_at(0.0) == pytest.approx(0.010) and lim.normal_cap_at(None) == 0.6


def test_with_a_normal_only_the_speed_towards_the_finger_falls_to_the_touch_speed():
    """The finger 0.5 mm over the device's face: the device still moves sideways at the near-finger
    cap (0.25 m/s), but towards the finger along the normal at most 10 mm/s (a cap on the 3-D
    distance held the sideways move to 10 mm/s as well)."""
    n = (0.0, 0.0, 1.0)
    lim = TravelLimiter(0.6, 40.0)
    lim.reset(0.0, 0.0, 0.0)
    out = [lim.step(k * 1e-3, 0.03, 0.0, 0.0, 0.0, 0.0, 0.0, finger_m=0.005, gap_m=0.0005, normal=n) for k in range(100)]
    v = np.array([o[3:] for o in out])
    assert np.linalg.norm(v, axis=1).max() == pytest.approx(lim.near_speed)
    lim.reset(0.0, 0.0, 0.0)
    out = [lim.step(k * 1e-3, 0.0, 0.0, 0.03, 0.0, 0.0, 0.0, finger_m=0.005, gap_m=0.0005, normal=n) for k in range(100)]
    vz = np.array([o[5] for o in out])
    assert vz.max() == pytest.approx(0.010) and vz.min() >= 0.0
    # away from the finger (down the normal) only the near-finger cap applies
    lim.reset(0.0, 0.0, 0.0)
    out = [lim.step(k * 1e-3, 0.0, 0.0, -0.03, 0.0, 0.0, 0.0, finger_m=0.005, gap_m=0.0005, normal=n) for k in range(100)]
    assert min(o[5] for o in out) == pytest.approx(-lim.near_speed)


def test_anchor_follows_the_arm_only_where_the_object_gain_let_go():
    lim = TravelLimiter(0.6, 40.0)
    lim.reset(0.0, 0.0, 0.0)
    eye = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    lim.anchor(0.01, 0.02, -0.005, 0.1, 0.0, -0.2, eye)
    assert lim._x == (0.0, 0.0, 0.0) and lim._v == (0.0, 0.0, 0.0)
    normal_free = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 0.0))  # λ_z = 0: the finger pushes the device in
    lim.anchor(0.01, 0.02, -0.005, 0.1, 0.0, -0.2, normal_free)
    assert lim._x == pytest.approx((0.0, 0.0, -0.005)) and lim._v == pytest.approx((0.0, 0.0, -0.2))
    # when the gain returns, the output leaves the arm's depth at the travel limits, not in one step
    out = lim.step(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    out = lim.step(0.001, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert out[2] < -0.004 and abs(out[5]) <= 0.2 + 40.0 * 0.001 + 1e-9


@pytest.mark.parametrize("accel", [10.0, 40.0])
def test_jumps_of_every_size_are_travelled_with_bounded_jerk_and_without_overshoot(accel):
    """0.2–50 mm jumps in three directions: speed, acceleration and jerk stay within their limits
    (the acceleration changes by at most jerk·dt a tick: the force the PD asks for has no steps), the
    remaining distance never grows, and the output ends on the target."""
    jerk, dt = 2000.0, 1e-3
    for d in (0.0002, 0.001, 0.003, 0.008, 0.012, 0.016, 0.02, 0.03, 0.05):
        for direction in ((1.0, 0.0, 0.0), (0.0, -0.6, 0.8), (0.48, 0.6, -0.64)):
            goal = d * np.asarray(direction)
            xs, vs, _ = _run(TravelLimiter(0.6, accel, jerk), goal, seconds=0.4)
            acc = np.diff(vs, axis=0) / dt
            assert np.linalg.norm(vs, axis=1).max() <= 0.6 + 1e-9
            assert np.linalg.norm(acc, axis=1).max() <= accel * (1 + 1e-9)
            assert np.linalg.norm(np.diff(acc, axis=0), axis=1).max() / dt <= jerk * (1 + 1e-6)
            dist = np.linalg.norm(xs - goal, axis=1)
            assert np.all(np.diff(dist) <= 1e-9), (d, direction)
            assert dist[-1] < 1e-6


def test_the_jerk_limit_takes_the_steps_out_of_the_force_the_servo_asks_for():
    """The same 20 mm move through the servo: with the jerk limit the PD's force changes by a
    fraction of what the bang-bang acceleration (an unlimited jerk) switches in one tick, and the move
    takes at most a little longer."""
    bang = _force_steps(TravelLimiter(0.6, 40.0, 1e9))
    smooth = _force_steps(TravelLimiter(0.6, 40.0, 1000.0))
    assert bang[0] > 0.4 and smooth[0] < 0.25 * bang[0]
    assert smooth[1] < bang[1] + 0.05


def _force_steps(travel, dy: float = 0.02):
    """(largest |ΔF_pd| in one tick, time to within 1 mm) for a ``dy`` target jump after settling."""
    from vishap.robot.gains import load_gains

    servo = build_servo(policy="hold", travel=travel, gains=load_gains(override={"vision_hz": 0.0})[0])
    ctrl = servo.controller
    for k in range(700):
        servo.tick(k * 1e-3)
    goal = np.array(ctrl.p) + np.array([0.0, dy, 0.0])
    F, t_in = [], None
    for k in range(700, 1000):
        servo.tick(k * 1e-3, goal)
        F.append(ctrl.F_pd)
        if t_in is None and np.linalg.norm(np.array(ctrl.p) - goal) < 1e-3:
            t_in = (k - 700) * 1e-3
    return float(np.linalg.norm(np.diff(np.array(F), axis=0), axis=1).max()), t_in


def test_the_caps_act_on_the_finger_predicted_ahead():
    """A finger closing at 0.5 m/s on a device travelling towards it: given the finger's state, the
    limiter is down to the near-finger speed while the finger is still ≈ 0.5 m/s·``lead_s`` further
    out than told only the distance now (the device follows its output some 30 ms late)."""
    def distance_when_slow(with_state):
        lim = TravelLimiter.for_approach(0.6, 40.0)
        lim.reset(0.0, 0.0, 0.0)
        f0, vf = 0.12, -0.5
        fast = False
        for k in range(200):
            t = k * 1e-3
            f = f0 + vf * t
            d = f - lim._x[0]
            out = lim.step(t, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, finger_m=abs(d),
                           finger=(f, 0.0, 0.0, vf, 0.0, 0.0) if with_state else None)
            fast = fast or out[3] > 0.4
            if fast and out[3] <= lim.near_speed + 1e-9:
                return d
        raise AssertionError("never slowed down")

    ahead, now = distance_when_slow(True), distance_when_slow(False)
    assert now <= TravelLimiter.for_approach().near_m + TravelLimiter.for_approach().margin_m + 1e-3
    assert ahead > now + 0.5 * 0.5 * TravelLimiter.for_approach().lead_s


def test_a_target_that_stops_dead_is_not_overrun():
    """The interpolating shaper's target runs at 0.3 m/s to its newest sample and stops there: told
    where it will stop (``rest``), the jerk-limited output brakes in time and never passes it; not
    told, it overruns by millimetres (it cannot stop dead)."""
    def run(with_rest):
        lim = TravelLimiter(0.6, 40.0, 1000.0)
        lim.reset(0.0, 0.0, 0.0)
        xs = []
        for k in range(300):
            t = k * 1e-3
            x, v = (0.3 * t, 0.3) if t < 0.05 else (0.015, 0.0)
            xs.append(lim.step(t, x, 0.0, 0.0, v, 0.0, 0.0, rest=(0.015, 0.0, 0.0) if with_rest else None)[0])
        return np.array(xs)

    told, blind = run(True), run(False)
    assert told.max() <= 0.015 + 1e-9 and abs(told[-1] - 0.015) < 1e-6
    assert blind.max() > 0.015 + 0.001


def test_the_output_brakes_to_stay_inside_the_workspace_box():
    """A target beyond the box's face, approached at full speed: the output slows down on its own and
    stops on the face (the controller would otherwise clamp the target dead at the face and the arm
    overrun it)."""
    lim = TravelLimiter(0.6, 40.0, 1000.0)
    lim.box = ((-0.1, -0.1, -0.1), (0.03, 0.1, 0.1))
    lim.reset(-0.05, 0.0, 0.0, 0.6, 0.0, 0.0)
    out = np.array([lim.step(k * 1e-3, 0.06, 0.0, 0.0, 0.0, 0.0, 0.0) for k in range(400)])
    assert out[:, 0].max() <= 0.03 + 1e-7 and out[-1, 0] == pytest.approx(0.03, abs=1e-6)
    assert np.linalg.norm(np.diff(out[:, 3:], axis=0), axis=1).max() <= 40.0e-3 + 1e-9


def test_the_servo_gives_its_limiter_the_workspace_box_and_the_shapers_rest_point():
    servo = build_servo(policy="interpolate", travel=TravelLimiter())
    lim = servo.controller.limits
    assert servo.travel.box == (tuple(lim.workspace_min), tuple(lim.workspace_max))
    servo.shaper.push(0.0, 0.1, 0.0, -0.1)
    servo.shaper.push(0.033, 0.11, 0.0, -0.1)
    assert servo.shaper.rest() == (0.11, 0.0, -0.1)
    ex = build_servo(policy="extrapolate", travel=TravelLimiter()).shaper
    ex.push(0.0, 0.1, 0.0, -0.1)
    ex.push(0.033, 0.11, 0.0, -0.1)
    assert ex.rest()[0] == pytest.approx(0.11 + 0.01 / 0.033 * ex.horizon * 0.033)


def test_a_cap_that_falls_faster_than_the_device_brakes_does_not_turn_it_back():
    """The approach configuration speeding towards a target 60 mm ahead when the finger's estimate
    jumps next to it (the cap falls from 0.6 to 0.22 m/s in one tick): the output steps down to the
    cap and goes on towards the target. The step is not kept as a 40 m/s² braking that the jerk limit
    would take 40 ms to unwind, running the output back away from its target."""
    lim = TravelLimiter.for_approach()
    lim.reset(0.0, 0.0, 0.0)
    vs = []
    for k in range(120):
        t = k * 1e-3
        near = t >= 0.03
        out = lim.step(t, 0.06, 0.0, 0.0, 0.0, 0.0, 0.0, finger_m=lim.near_m if near else None)
        if near:
            vs.append(out[3])
    vs = np.array(vs)
    assert vs[0] == pytest.approx(lim.near_speed)  # it was faster than the cap: stepped down at once
    assert vs.max() <= lim.near_speed + 1e-9
    assert vs[:40].min() > 0.9 * lim.near_speed  # still on its way at the cap, not braking through zero


def test_of_several_finger_estimates_the_nearest_caps_the_speed():
    """Given two estimates of the finger (the world's and the caps' faster one), the limiter caps on
    the one that puts the finger nearer; a far one never lifts the cap a near one set, and one estimate
    alone gives the same output as before."""
    def run(finger):
        lim = TravelLimiter.for_approach(0.6, 40.0)
        lim.reset(0.0, 0.0, 0.0)
        for k in range(300):
            out = lim.step(k * 1e-3, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0, finger_m=0.2, finger=finger)
        return out, lim.speed_cap

    near = (0.14, 0.0, 0.0, 0.0, 0.0, 0.0)  # the finger 5 mm beyond where the output would be after 0.3 s at the cap
    far = (0.5, 0.0, 0.0, 0.0, 0.0, 0.0)
    cap_near = run(near)[1]
    assert run((far, near))[1] == run((near, far))[1] == cap_near
    assert run((far, near))[0] == run(near)[0]
    assert run(far)[1] == 0.6 and cap_near < 0.6
    assert run((far, far))[0] == run(far)[0]


def test_a_non_finite_finger_estimate_never_lifts_the_cap_another_set():
    """Beside an estimate that puts the finger 15 mm over the face, one with a non-finite velocity
    (a corrupt record's fields) leaves the output's speed towards the finger at the normal cap."""
    def run(finger):
        lim = TravelLimiter.for_approach(0.6, 40.0)
        lim.reset(0.0, 0.0, 0.0)
        for k in range(300):
            out = lim.step(k * 1e-3, 0.0, 0.0, 0.2, 0.0, 0.0, 0.0, finger_m=0.015, gap_m=0.015, normal=(0.0, 0.0, 1.0),
                           finger=finger)
        return out

    near = (0.0, 0.0, 0.015, 0.0, 0.0, 0.0)
    alone = run(near)
    assert alone[5] < 0.05  # held to the normal cap near the finger
    for bad in ((0.0, 0.0, 0.015, math.inf, 0.0, 0.0), (math.nan, 0.0, 0.015, 0.0, 0.0, 0.0),
                (0.0, 0.0, 0.015, 0.0, 0.0, -math.inf)):
        assert run((near, bad)) == run((bad, near)) == alone
