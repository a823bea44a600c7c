"""The object-gain scheduler: few Λ changes, each ramped, no chatter on a noisy depth, force ramps."""
import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.robot.controller import Controller
from vishap.robot.object_gain import ENGAGED, FREE, SURFACE, ObjectGainScheduler

DT = 1e-3


def _run(sched, depths, *, imminent=True, actions=None, t0=0.0):
    Ls, scales, states = [], [], []
    for i, d in enumerate(depths):
        a = "track" if actions is None else actions[i]
        L, s = sched.step(t0 + i * DT, float(d), imminent, d > 0, a)
        Ls.append(np.array(L))
        scales.append(s)
        states.append(sched.state)
    return np.array(Ls), np.array(scales), states


def _changes(states):
    return sum(1 for a, b in zip(states, states[1:]) if a != b)


def _approach(rng, sigma=40e-6):
    """Device approaching the surface, touching, pressed in 3 mm, then held — with encoder-like noise."""
    d = np.concatenate([np.linspace(-0.02, 0.0, 300), np.linspace(0.0, 0.003, 200), np.full(500, 0.003)])
    return d + rng.normal(0.0, sigma, d.size)


def test_an_approach_changes_lambda_at_most_twice_each_over_20ms():
    rng = np.random.default_rng(0)
    s = ObjectGainScheduler(dt=DT)
    s.set_subject((0.0, 0.0, 0.0), np.eye(3))
    Ls, _, states = _run(s, _approach(rng))
    assert _changes(states) == 2 and states[-1] == ENGAGED
    assert np.allclose(Ls[0], np.eye(3)) and np.allclose(Ls[-1], 0.0)
    # each change is a linear blend: no entry moves by more than dt / 20 ms per tick
    assert np.max(np.abs(np.diff(Ls, axis=0))) <= DT / 0.020 + 1e-12
    # and each blend took at least 20 ms: count the ticks during which Λ moved
    moving = np.any(np.abs(np.diff(Ls, axis=0)) > 1e-12, axis=(1, 2))
    runs = np.diff(np.flatnonzero(np.diff(np.r_[0, moving.astype(int), 0])))[::2]
    assert len(runs) == 2 and np.all(runs >= 20)


def test_no_chatter_with_noisy_depth_sitting_on_each_threshold():
    rng = np.random.default_rng(1)
    for level in (0.0001, 0.0003, -0.001):  # surface_on, engage, release thresholds
        s = ObjectGainScheduler(dt=DT)
        s.set_subject((0.0, 0.0, 0.0), np.eye(3))
        _run(s, np.linspace(-0.005, 0.0006, 200))  # brings the state to ENGAGED
        d = level + rng.normal(0.0, 60e-6, 2000)  # 2 s of noise around the threshold
        _, _, states = _run(s, d, t0=0.2)
        assert _changes(states) <= 2, level


def test_a_naive_threshold_would_chatter_on_the_same_depth():
    # the same noisy depth through the old rule (Λ = contact gain iff depth > engage_m) flips often:
    # the test above is only meaningful because this one does
    rng = np.random.default_rng(1)
    d = 0.0003 + rng.normal(0.0, 60e-6, 2000)
    flips = np.count_nonzero(np.diff((d > 0.0003).astype(int)))
    assert flips > 100


def test_retreat_releases_at_once_and_the_force_ramps_after_hold_and_retreat():
    s = ObjectGainScheduler(dt=DT, force_ramp_s=0.1)
    s.set_subject((1.0, 1.0, 0.0), np.eye(3))
    acts = ["idle"] * 50 + ["track"] * 300 + ["hold"] * 100 + ["retreat"] * 100 + ["track"] * 300
    d = np.full(len(acts), 0.002)
    Ls, sc, states = _run(s, d, actions=acts)
    assert np.all(sc[:50] == 0.0)
    assert sc[50] == 0.0 and sc[99] == pytest.approx(0.49) and sc[200] == 1.0  # ramp when tracking starts
    assert states[460] == FREE  # retreat: released without waiting for the dwell
    assert sc[550] == 0.0 and sc[600] == pytest.approx(0.5)  # ramp again when tracking resumes
    assert np.max(np.diff(sc)) <= DT / 0.1 + 1e-12  # the scale never jumps up
    assert np.max(np.abs(np.diff(Ls, axis=0))) <= DT / 0.020 + 1e-12


def test_lambda_is_rotated_into_the_robot_frame():
    c, s_ = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]])
    sch = ObjectGainScheduler(dt=DT)
    sch.set_subject((0.0, 0.0, 0.0), R)
    _run(sch, np.linspace(-0.001, 0.0003, 100))
    assert sch.state == SURFACE
    L, _ = sch.step(1.0, 0.0002, True, True, "track")
    assert np.allclose(np.array(L), R @ np.diag([1.0, 1.0, 0.0]) @ R.T)


def test_controller_takes_the_scheduled_lambda_and_scale():
    ctrl = Controller()
    sch = ObjectGainScheduler(dt=DT)
    sch.set_subject((0.0, 0.0, 0.0), None)
    L, s = sch.step(0.0, -0.01, True, False, "track")
    ctrl.set_lambda_robot(L)
    ctrl.force_scale = s
    assert np.allclose(ctrl.lambda_robot, np.eye(3))
    ctrl.compute(1.0, 0, 0, 0, 0, 0, 0, 0.225, 0.0, -0.17)
    assert ctrl.F_pd == (0.0, 0.0, 0.0)  # scale 0 at the start of tracking
    ctrl.set_lambda_robot(((0.5, 0, 0), (0, 0.5, 0), (0, 0, 0.0)))
    ctrl.force_scale = 1.0
    ctrl.compute(2.0, 0, 0, 0, 0, 0, 0, 0.225, 0.0, -0.16)
    assert ctrl.F_pd[2] == pytest.approx(0.0) and ctrl.F_pd[0] != 0.0


@pytest.mark.parametrize("kw", [{"ramp_s": 0.01}, {"engage_m": 0.00005}, {"dwell_s": float("nan")}, {"dt": 0.0}])
def test_bad_settings_name_the_field(kw):
    with pytest.raises(ConfigError) as e:
        ObjectGainScheduler(**kw)
    assert next(iter(kw)) in str(e.value)


def test_the_surface_handover_starts_before_a_predicted_touch_and_a_resume_in_contact_keeps_the_force():
    s = ObjectGainScheduler(dt=DT)
    s.set_subject((0.0, 0.0, 0.0), np.eye(3))
    s.step(0.0, -0.0002, True, False, "track", touch_in_s=0.2)
    assert s.state == FREE  # the finger is still far (in time): the servo holds the surface
    s.step(0.001, -0.0002, True, False, "track", touch_in_s=0.02)
    assert s.state == SURFACE and s.changing  # it lands within the blend: hand the normal to the law now
    assert not s.law_active  # no force above the surface
    s.step(0.002, -0.003, True, False, "track", touch_in_s=0.01)
    assert s.state == SURFACE  # the dwell keeps a brief excursion from flipping Λ back
    s2 = ObjectGainScheduler(dt=DT, force_ramp_s=0.1)
    s2.set_subject((0.0, 0.0, 0.0), np.eye(3))
    acts = ["track"] * 200 + ["hold"] * 100 + ["track"] * 50
    _, sc, states = _run(s2, np.full(len(acts), 0.002), actions=acts)
    assert states[299] != FREE and np.all(sc[150:] == 1.0)  # held and resumed on the finger: no force dip


def test_a_restarted_force_ramp_blends_from_the_held_force_without_a_step():
    """Resuming tracking after a hold restarts the scale at 0: the force the controller was giving fades
    out as the new one fades in (a scale that simply fell to 0 dropped a 0.9 N hold force in one tick)."""
    ctrl = Controller()
    args = (0.0, 0.5, 0.3, 0.0, 0.0, 0.0)  # a still arm
    for k in range(600):  # tracking, ramped up, pulled 1 mm off its target: ≈ 0.8 N
        ctrl.compute(k * DT, *args, 0.226, 0.0, -0.17)
    held = np.array(ctrl.F_pd)
    assert np.linalg.norm(held) > 0.5
    sch = ObjectGainScheduler(dt=DT, force_ramp_s=0.1)
    sch.set_subject((0.0, 0.0, 0.0), None)
    F = [held]
    for i, a in enumerate(["track"] * 5 + ["hold"] * 20 + ["track"] * 150):  # resume toward a target 20 mm off
        _, s = sch.step(i * DT, -0.02, False, False, a)
        ctrl.force_scale = s
        ctrl.compute(0.6 + i * DT, *args, 0.245 if i >= 25 else 0.226, 0.0, -0.17)
        F.append(np.array(ctrl.F_pd))
    F = np.array(F)
    steps = np.linalg.norm(np.diff(F, axis=0), axis=1)
    assert steps.max() < 0.5  # issue 16: ≤ 0.5 N per tick (dropping the held force was one step of |held|)
    assert np.allclose(F[26], held, atol=0.02)  # at the restart the force is still the held one
    assert np.linalg.norm(F[-1] - held) > 5.0  # and the new command has taken over after the ramp


def test_a_brief_dip_past_engage_does_not_engage_but_a_push_that_stays_does():
    """The device's own bounce on the law's spring (or a dip while it travels at the surface) crosses
    engage_m for a few ticks: engaging on it released the wall's lateral axes and flipped Λ back again
    (4 changes in one wall approach); a finger's push stays there and engages after engage_s."""
    s = ObjectGainScheduler(dt=DT)
    s.set_subject((0.0, 0.0, 0.0), np.eye(3))
    d = np.concatenate([np.linspace(-0.002, 0.0002, 100), np.full(100, 0.0002),  # to the surface state
                        np.full(16, 0.00035), np.full(100, -0.0001),  # a 16 ms dip past engage_m, then back up
                        np.full(300, 0.002)])  # a finger pushes 2 mm in and stays
    _, _, states = _run(s, d)
    assert states[199] == SURFACE and all(st == SURFACE for st in states[199:316])
    k = next(i for i, st in enumerate(states) if st == ENGAGED)
    assert k - 316 == pytest.approx(s.engage_s / DT, abs=1)
    assert _changes(states) == 2
    # the rule without the wait engages on the dip, and leaves again once the dwell allows
    s0 = ObjectGainScheduler(dt=DT, engage_s=0.0)
    s0.set_subject((0.0, 0.0, 0.0), np.eye(3))
    _, _, states0 = _run(s0, d)
    assert states0[205] == ENGAGED and _changes(states0) == 4


def test_a_new_subject_away_from_the_device_releases_lambda_at_once_over_one_ramp():
    """The world switched the subject (it never does under a touching finger) while the device waited
    at the old one's surface: that interaction is over, so Λ goes back to free without waiting out the
    dwell (waiting kept the panel shelf's released normal for 50 + 25 ms while the world sent the device
    up over the shelf's edge to a key 20 mm lower, and it reached the key after the finger). Still one
    change, ramped over ``ramp_s``; a new subject whose surface the device is already at changes nothing."""
    s = ObjectGainScheduler(dt=DT)
    s.set_subject((0.0, 0.0, 0.0), np.eye(3))
    _, _, states = _run(s, np.full(30, 0.0002))  # waiting at the shelf's surface: λ_z released
    assert states[-1] == SURFACE and s.n_changes == 1
    s.set_subject((1.0, 1.0, 1.0), np.eye(3))  # a key, its surface 20 mm under the device
    Ls, _, states = _run(s, np.full(60, -0.02), t0=0.030)
    assert states[0] == FREE and s.n_changes == 2  # at once, 30 ms after the last change (dwell 50 ms)
    zz = Ls[:, 2, 2]
    assert np.max(np.diff(zz)) <= DT / s.ramp_s + 1e-12 and zz[0] < 0.1 and zz[int(s.ramp_s / DT)] == 1.0
    # the same excursion without a new subject is held for the dwell: a brief lift is not an ending
    s2 = ObjectGainScheduler(dt=DT)
    s2.set_subject((0.0, 0.0, 0.0), np.eye(3))
    _, _, st2 = _run(s2, np.r_[np.full(30, 0.0002), np.full(60, -0.02)])
    assert st2[30] == SURFACE and st2[-1] == FREE
    # a new subject whose surface the device is at (a neighbour in the same plane): no change
    s3 = ObjectGainScheduler(dt=DT)
    s3.set_subject((0.0, 0.0, 0.0), np.eye(3))
    _run(s3, np.full(30, 0.0002))
    s3.set_subject((0.0, 0.0, 0.0), np.eye(3))
    _, _, st3 = _run(s3, np.full(30, 0.0002), t0=0.030)
    assert all(st == SURFACE for st in st3) and s3.n_changes == 1
