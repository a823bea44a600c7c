"""The core's scene step, contact renderer and servo step (vishap.runtime.core)."""
import numpy as np
import pytest

from vishap.runtime.core import HOLD_BAND_M, ContactRenderer, RestPlay, SceneStep, TargetRecord
from vishap.world.scene import load_scene
from vishap.world.world import World


def test_record_packs_and_unpacks_every_field():
    r = TargetRecord(7, (0.1, 0.2, -0.3), 1.5, 0.8, False, True, 2, True, False, (1.0, 2.0, 3.0), (0.1, 0.0, -0.2), 1.52,
                     lost=True, finger_fast=(1.1, 2.1, 3.1), finger_fast_velocity=(0.2, 0.0, -0.3))
    a = r.pack()
    assert a.dtype == np.float64 and a.shape == (25,)
    assert TargetRecord.unpack(a) == r
    p, v = r.finger_at(1.62)
    assert np.allclose(p, [1.01, 2.0, 2.98]) and np.allclose(v, [0.1, 0.0, -0.2])


def test_scene_step_maps_the_cap_centre_to_the_pad_and_the_target_to_the_end_effector():
    scene = load_scene("wall")
    T = np.eye(4)
    T[:3, 3] = [0.1, 0.0, 0.0]
    step = SceneStep(World(scene, predictor="none"), T, tip_radius_m=0.008, mount_offset=(0.03, 0.0, 0.0))
    rec, inter, pad = step.step(0.0, False, np.full(3, np.nan), 0.0, None)
    assert not rec.armed and inter is None  # nothing seen yet: the servo holds
    rec, inter, pad = step.step(0.1, True, [0.1, 0.0, -0.142], 0.9, None)
    assert np.allclose(pad, [0.2, 0.0, -0.150])
    assert rec.armed and rec.seq == 2 and rec.made_at == 0.1 and rec.confidence == 0.9
    assert np.allclose(rec.X_ee, inter.X_d - [0.03, 0.0, 0.0])
    assert rec.subject == 0 and rec.in_contact and rec.imminent
    # no calibration: the record says so and carries no target
    lost = SceneStep(World(scene, predictor="none"), None, tip_radius_m=0.008, mount_offset=(0.03, 0.0, 0.0))
    rec, inter, _ = lost.step(0.0, True, [0.1, 0.0, -0.142], 0.9, None)
    assert not rec.calibrated and rec.armed and inter is None and not np.isfinite(rec.X_ee).any()


def test_contact_renderer_gates_the_law_and_schedules_the_object_gain():
    scene = load_scene("wall")
    c = ContactRenderer(scene.objects, max_force_n=8.5, engage_m=0.0003)
    z0 = np.zeros(3)

    def at(z):
        return np.array([0.2, 0.0, z])

    F, L, scale = c.update(0.0, at(-0.151), z0, 0, False, False, "track")
    assert F is None and c.state_code == 0 and np.allclose(L, np.eye(3))  # nothing announced: free
    F, L, _ = c.update(0.001, at(-0.1502), z0, 0, True, True, "track")
    assert F[2] == pytest.approx(800.0 * 0.0002) and c.state_code == 1  # under the surface: the law acts
    assert c.gain.changing and L[2][2] == 1.0  # Λ blends toward diag(1, 1, 0), never in one tick
    F, L, _ = c.update(0.010, at(-0.152), z0, 0, True, True, "track")
    assert F[2] == pytest.approx(1.6) and c.state_code == 1  # pushed in, but the dwell holds the state
    assert 0.0 < L[2][2] < 1.0 and L[0][0] == 1.0
    for k in range(11, 100):
        F, L, _ = c.update(k * 1e-3, at(-0.152), z0, 0, True, True, "track")
    assert c.state_code == 2 and np.allclose(L, np.zeros((3, 3)))  # engaged: the wall's Λ, blend done
    assert c.gain.n_changes == 2  # free → surface → engaged: two changes in the approach
    F, L, _ = c.update(0.100, at(-0.1495), z0, 0, True, True, "track")
    assert F is None and c.state_code == 2  # a hair above the surface: no force, but no flip of Λ yet
    F, L, _ = c.update(0.101, at(-0.152), z0, 0, True, True, "retreat")
    assert F is None and c.state_code == 0  # the guard retreats: free at once (the blend follows)
    panel = load_scene("panel")
    k = [o.name for o in panel.objects].index("key_b")
    kb = ContactRenderer(panel.objects, max_force_n=8.5)
    for i in range(100):
        F, L, _ = kb.update(i * 1e-3, np.array([0.23, 0.04, -0.152]), z0, k, True, True, "track")
    assert np.allclose(np.diag(L), (1.0, 1.0, 0.0)) and F[2] > 0  # a key stays put laterally
    # the subject's own law, saturated at the device's force limit
    F, _, _ = kb.update(0.1, np.array([0.23, 0.04, -0.151]), z0, k, True, True, "track")
    assert F[2] == pytest.approx(500.0 * 0.001)
    small = ContactRenderer(scene.objects, max_force_n=1.0)
    assert np.linalg.norm(small.update(0.0, at(-0.160), z0, 0, True, True, "track")[0]) == pytest.approx(1.0)


def test_servo_step_renders_the_law_only_while_announced_and_tracking_or_holding():
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device

    scene = load_scene("wall")
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco())
    step = make_servo_step(dev, scene)
    p_in = scene.objects[0].centre - np.array([0.0, 0.0, 0.002])  # contact point 2 mm under the wall
    X_ee = tuple(p_in - step.mount)
    dev.reset(kinematics.ik(np.asarray(X_ee)))
    on = TargetRecord(1, X_ee, 0.0, 1.0, True, True, 0, True, True)
    for k in range(101):
        on.made_at = k * 1e-3
        tk = step.tick(k * 1e-3, on)
    assert tk.action == "track" and tk.F_law is not None and tk.F_law[2] > 0
    assert tk.lambda_state == 2 and np.allclose(step.controller.lambda_robot, np.zeros((3, 3)))  # the wall's Λ
    assert step.controller.force_scale == 1.0  # ramped up since tracking began
    bad = TargetRecord(2, (np.nan,) * 3, 0.101, 1.0, True, True, 0, True, True)
    tk = step.tick(0.101, bad)
    assert tk.action == "hold" and tk.F_law is not None  # holding keeps rendering the wall
    off = TargetRecord(3, X_ee, 0.102, 1.0, False, True, 0, True, True)
    for k in range(102, 140):
        tk = step.tick(k * 1e-3, off)
        assert tk.action == "retreat" and tk.F_law is None and tk.lambda_state == 0
    assert np.allclose(step.controller.lambda_robot, np.eye(3))  # blended back to free motion


def test_servo_step_holds_a_pressed_device_while_vision_has_lost_the_finger_and_retreats_once_let_go():
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device

    scene = load_scene("wall")
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco())
    step = make_servo_step(dev, scene, retreat_after_s=0.3)
    X_ee = tuple(scene.objects[0].centre - step.mount)
    dev.reset(kinematics.ik(np.asarray(X_ee)))
    push = np.array([0.0, 0.0, -1.0])  # a finger pressing 1 N on the face
    seen = lambda k, c: TargetRecord(k + 1, X_ee, k * 1e-3, c, True, True, 0, True, True)  # noqa: E731
    for k in range(300):  # tracking, the force ramped up
        tk = step.tick(k * 1e-3, seen(k, 1.0))
    for k in range(300, 600):  # the finger presses, seen
        dev.apply_tip_force(push)
        tk = step.tick(k * 1e-3, seen(k, 1.0))
    assert tk.action == "track" and tk.pressed and tk.F_law is not None
    for k in range(600, 1600):  # vision loses the finger for 1 s; it keeps pressing
        dev.apply_tip_force(push)
        tk = step.tick(k * 1e-3, seen(k, 0.0))
        assert tk.action == "hold" and tk.F_law is not None, k
    dev.apply_tip_force(np.zeros(3))  # the finger lets go, still unseen
    actions = [step.tick(k * 1e-3, seen(k, 0.0)).action for k in range(1600, 2100)]
    assert actions[0] == "hold" and actions[-1] == "retreat"
    assert 300 <= actions.index("retreat") <= 400  # 0.3 s after the device is let go (it rises out first)


@pytest.mark.parametrize("arg, value", [("hold_friction_n", float("nan")), ("hold_ramp_m", -3e-5),
                                        ("max_force_n", 0.0), ("max_force_n", float("inf")),
                                        ("hold_friction_n", "0.04 N")])
def test_the_renderer_refuses_a_setting_that_is_not_a_finite_number_in_range_naming_it(arg, value):
    """A NaN friction or a negative ramp would put a NaN or a pull away from the face into every held tick."""
    from vishap._core.errors import ConfigError

    kwargs = {"max_force_n": 8.5, arg: value}
    with pytest.raises(ConfigError) as err:
        ContactRenderer(load_scene("wall").objects, **kwargs)
    assert err.value.field == arg
    ContactRenderer(load_scene("wall").objects, max_force_n=8.5, hold_friction_n=0.0, hold_ramp_m=0.0)


def test_the_renderer_takes_laws_built_by_the_caller_one_per_object():
    """The stability sweep's laws (stiffer than a scene may hold) are rendered as given; a list that does
    not match the objects is refused naming ``laws``."""
    from vishap._core.errors import ConfigError
    from vishap.robot.stability import contact_law

    objects = load_scene("wall").objects
    law = contact_law("hard_wall", 5000.0, 2.0)  # make_law would refuse 5000 N/m at 2 N·s/m
    r = ContactRenderer(objects, max_force_n=8.5, laws=[law])
    assert r.laws[0] is law
    with pytest.raises(ConfigError) as err:
        ContactRenderer(objects, max_force_n=8.5, laws=[law, law])
    assert err.value.field == "laws"


def test_the_renderer_holds_a_device_above_the_surface_there_while_it_renders_the_surface():
    """Over the band the hold pulls with the law's spring on the height beyond it, its damping and the
    arm's friction (so it brings the face into the band); inside the band only the damping of a face
    moving away."""
    scene = load_scene("wall")
    fr = 0.04
    c = ContactRenderer(scene.objects, max_force_n=8.5, hold_friction_n=fr)
    z0 = np.zeros(3)
    top = scene.objects[0].centre[2]
    assert c.update(0.0, np.array([0.2, 0.0, top + 0.0005]), z0, 0, True, False, "track")[0] is None
    assert c.F_hold is None  # free motion: the position servo holds the device, not the renderer
    c.update(0.001, np.array([0.2, 0.0, top - 0.0002]), z0, 0, True, False, "track")  # dipped in: surface
    assert c.state_code == 1
    F, _, _ = c.update(0.002, np.array([0.2, 0.0, top + 0.0003]), z0, 0, True, False, "track")
    # pulled back with the wall's own spring beyond the band and the friction it must overcome
    assert F is None and c.F_hold[2] == pytest.approx(-800.0 * (0.0003 - HOLD_BAND_M) - fr)
    _, _, _ = c.update(0.003, np.array([0.2, 0.0, top + 0.0003]), np.array([0.0, 0.0, 0.05]), 0, True, False, "track")
    assert c.F_hold[2] == pytest.approx(-800.0 * (0.0003 - HOLD_BAND_M) - fr - 2.0 * 0.05)  # and its damping, moving away
    c.update(0.004, np.array([0.2, 0.0, top + HOLD_BAND_M + 1e-7]), z0, 0, True, False, "track")
    assert c.F_hold[2] == pytest.approx(-fr, abs=1e-3)  # just over the band: the friction's worth
    for h in (HOLD_BAND_M - 1e-7, 0.5 * HOLD_BAND_M, 1e-7):
        c.update(0.005, np.array([0.2, 0.0, top + h]), z0, 0, True, False, "track")
        assert c.F_hold is None  # inside the band the arm's friction holds the face: no pull
        c.update(0.005, np.array([0.2, 0.0, top + h]), np.array([0.0, 0.0, -0.05]), 0, True, False, "track")
        assert c.F_hold is None  # nor against a face moving towards the surface
        c.update(0.005, np.array([0.2, 0.0, top + h]), np.array([0.0, 0.0, 0.05]), 0, True, False, "track")
        assert c.F_hold[2] == pytest.approx(-2.0 * 0.05)  # only the damping of a face moving away
    c.update(0.006, np.array([0.2, 0.0, top + 0.0009]), z0, 0, True, False, "track")
    assert -800.0 * 0.0005 - fr < c.F_hold[2] < 0.0  # fading out before the release height: no step there
    c.update(0.007, np.array([0.2, 0.0, top + 0.0002]), z0, 0, False, False, "track")
    assert c.state_code == 0 and c.F_hold is None  # the interaction is over: free, the servo holds again


def test_the_holds_friction_share_grows_over_one_encoder_count_beyond_the_band():
    """With ``hold_ramp_m`` the friction's share of the pull grows from 0 at the band's edge to whole
    one ramp beyond it, so the pull is continuous in the height the encoders read: a reading one
    small step over the edge no longer unsticks the arm under a landing pad."""
    scene = load_scene("wall")
    fr, ramp = 0.04, 3e-5
    c = ContactRenderer(scene.objects, max_force_n=8.5, hold_friction_n=fr, hold_ramp_m=ramp)
    z0 = np.zeros(3)
    top = scene.objects[0].centre[2]
    c.update(0.0, np.array([0.2, 0.0, top - 0.0002]), z0, 0, True, False, "track")  # dipped in: surface
    pulls = []
    for e in (1e-7, 3e-6, 1.5e-5, 3e-5, 6e-5):
        c.update(0.001, np.array([0.2, 0.0, top + HOLD_BAND_M + e]), z0, 0, True, False, "track")
        assert c.F_hold[2] == pytest.approx(-800.0 * e - fr * min(1.0, e / ramp))
        pulls.append(-c.F_hold[2])
    assert pulls[0] < 1e-3 and pulls[1] < 0.2 * fr and pulls[3] > fr  # from nothing to more than the friction
    assert np.all(np.diff(pulls) > 0)


def test_the_servo_step_hold_cancels_the_device_friction_from_its_parameters():
    from vishap.runtime.assembly import make_servo_step, open_device

    scene = load_scene("wall")
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco())
    step = make_servo_step(dev, scene)
    assert step.contact.hold_friction_n == dev.params.coulomb_friction_n > 0.0
    # its share grows over one encoder count at the tip: the data sheet's 0.03 mm resolution
    assert step.contact.hold_ramp_m == pytest.approx(dev.params.tip_resolution_m) == pytest.approx(3.2e-5, rel=0.05)


def test_the_rest_play_holds_the_lateral_target_under_a_resting_finger_and_follows_larger_moves():
    n = (0.0, 0.0, 1.0)
    play = RestPlay(play_m=0.0005, near_m=0.002)
    X0 = np.array([0.1, 0.0, 0.05])
    assert play.apply(X0, n, 0.0005, True) is X0  # the play starts where the target is: no jump
    out = play.apply(X0 + [0.0003, -0.0002, 0.0001], n, 0.0005, True)
    assert np.allclose(out, X0 + [0.0, 0.0, 0.0001])  # sideways jitter absorbed, the normal passes
    out = play.apply(X0 + [0.0008, 0.0, 0.0], n, 0.0, True)
    assert np.allclose(out, X0 + [0.0003, 0.0, 0.0])  # a larger move followed, play_m behind
    out = play.apply(X0 + [0.0006, 0.0, 0.0], n, 0.0, True)
    assert np.allclose(out, X0 + [0.0003, 0.0, 0.0])  # and back within the play: still
    X = X0 + [0.0006, 0.0, 0.0]
    assert play.apply(X, n, 0.003, True) is X  # the finger above near_m: the target passes
    assert play.apply(X, n, 0.0, False) is X  # free motion: the target passes
    assert play.apply(X, n, float("nan"), True) is X  # no finger estimate: the target passes
    # a finger landing while it moves sideways (the world's run-up under it): the target passes
    assert play.apply(X0, n, 0.0, True, (0.03, 0.0, -0.01)) is X0
    assert play.apply(X, n, 0.0, True, (0.03, 0.0, -0.01)) is X
    play.apply(X, n, 0.0, True)  # it comes to rest: the play starts, and lasts while the finger stays near
    assert np.allclose(play.apply(X + [0.0003, 0.0, 0.0], n, 0.0, True, (0.03, 0.0, 0.0)), X)


def test_the_servo_step_takes_up_a_resting_fingers_sideways_jitter_at_the_surface():
    """A finger resting on the face, its lateral estimate jittering 0.2 mm per record: once the surface is
    rendered the servo's target stays put (the play); free of the finger, the target follows again."""
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device

    scene = load_scene("wall")
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco())
    step = make_servo_step(dev, scene)
    top = scene.objects[0].centre
    X0 = np.asarray(top - step.mount)
    dev.reset(kinematics.ik(X0))
    xs = []
    for k in range(600):
        t = k * 1e-3
        j = 0.0002 * (-1) ** (k // 33)  # a new lateral estimate every vision frame
        rec = TargetRecord(k // 33 + 1, tuple(X0 + [j, 0.0, 0.0]), (k // 33) * 0.033, 1.0, True, True, 0, True, True,
                           tuple(top + [j, 0.0, 0.0]), (0.0, 0.0, 0.0), t)
        tk = step.tick(t, rec)
        if tk.lambda_state == 1:
            xs.append(tk.X_ee[0] - X0[0])
    assert len(xs) > 300 and np.ptp(xs[-300:]) == 0.0  # at the surface the target stood still
    rec = TargetRecord(1000, tuple(X0 + [0.0002, 0.0, 0.0]), 0.7, 1.0, True, True, 0, True, True,
                       tuple(top + [0.0002, 0.0, 0.01]), (0.0, 0.0, 0.0), 0.7)
    assert step.tick(0.7, rec).X_ee[0] - X0[0] == pytest.approx(0.0002)  # the finger 10 mm up: no play


class _LandingFinger:
    """A finger that comes down at 20 mm/s, stops on the face and then presses at 2 mm/s."""

    finger_dir = (0.0, 0.0, -1.0)

    def __init__(self, top):
        self.top = top

    def pad(self, t, rec):
        if t < 1.0:
            h, v = max(0.0, 0.010 - 0.02 * max(t - 0.5, 0.0)), (-0.02 if 0.5 < t < 1.0 else 0.0)
        else:
            h, v = -0.002 * (t - 1.0), -0.002
        return self.top + np.array([0.0, 0.0, h]), np.array([0.0, 0.0, v if h > 0 or t >= 1.0 else 0.0])


def test_a_finger_landing_on_the_encoder_device_makes_contact_once():
    """Contact makes once (the demos had 3–17 makes in a touch): the simulated finger touches the device
    where it is, not where its encoders say (their 30 µm steps had made the pad force itself chatter)."""
    from vishap.apps.cycle import ServoCycle
    from vishap.apps.log import SignalLog
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device

    scene = load_scene("wall")
    obj = scene.objects[0]
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco(), substeps=10, sensor="encoder")
    step = make_servo_step(dev, scene)
    X = tuple(obj.centre - step.mount)
    dev.reset(kinematics.ik(np.asarray(X)))
    finger = _LandingFinger(np.asarray(obj.centre, float))
    log = SignalLog()
    cyc = ServoCycle(step, scene_object=obj, log=log, finger=finger, half_size_m=scene.passive_object.half_size_m)
    for k in range(1400):
        t = k * 1e-3
        p, v = finger.pad(t, None)
        cyc.servo(t, TargetRecord(k + 1, X, t, 1.0, True, True, 0, t > 0.3, t > 1.0, tuple(p), tuple(v), t))
    sv = log.channel("servo").arrays()
    ic = np.asarray(sv["in_contact"], bool)
    assert ic[-1] and int(np.count_nonzero(np.diff(ic.astype(int)) == 1)) == 1
    assert 0.0 < float(sv["F_contact"][-1][2]) < 2.0  # pressed 0.8 mm into the wall: the law pushes back



def test_scene_step_takes_visions_lost_report_and_falls_back_to_a_dropped_track():
    scene = load_scene("wall")
    step = SceneStep(World(scene, predictor="none"), np.eye(4), tip_radius_m=0.008, mount_offset=(0.03, 0.0, 0.0))
    assert not step.step(0.0, True, [0.2, 0.0, -0.12], 1.0, None)[0].lost
    # vision says the finger is gone while its tracker still coasts (confidence 0.6): lost
    assert step.step(1 / 30, False, np.full(3, np.nan), 0.6, None, lost=True)[0].lost
    # vision says a hidden fingertip is not a loss: not lost
    assert not step.step(2 / 30, False, np.full(3, np.nan), 0.6, None, lost=False)[0].lost
    # a source with no report (a camera model, an old log): lost once the tracker's confidence is 0
    assert not step.step(3 / 30, False, np.full(3, np.nan), 0.36, None)[0].lost
    assert step.step(4 / 30, False, np.full(3, np.nan), 0.0, None)[0].lost
    # a fix is never lost, whatever the report
    assert not step.step(5 / 30, True, [0.2, 0.0, -0.12], 1.0, None, lost=True)[0].lost


def test_the_servo_caps_near_the_finger_take_the_nearer_of_the_worlds_and_the_fast_estimate():
    """A finger starting a reach from rest towards the device: the scene step's record carries, beside
    the world's estimate, the caps' own faster one (vishap.world.predictor.near_predictor), which puts
    the finger nearer while the world's velocity lags; the servo step hands both to the travel limiter."""
    from vishap._core.motion import min_jerk
    from vishap.world.predictor import KalmanPredictor

    scene = load_scene("wall")
    step = SceneStep(World(scene, predictor=KalmanPredictor(meas_std_m=0.0036)), np.eye(4), tip_radius_m=0.0,
                     mount_offset=(0.0, 0.0, 0.0))
    assert np.isclose(step.near.R[0, 0], 0.0036 ** 2)  # the world's measurement noise
    top = scene.objects[0].centre + np.array([0.0, 0.0, 0.05])
    for k in range(11):  # at rest, then 50 mm down in 0.3 s (peak 3.2 m/s²), at 30 Hz, up to 133 ms in
        t = k / 30.0
        p = top - np.array([0.0, 0.0, 0.05]) * min_jerk(max(t - 0.2, 0.0) / 0.3)
        rec, _, _ = step.step(t, True, p, 1.0, None)
    t_f = rec.finger_t
    v_true = -0.05 * (min_jerk((t_f - 0.2 + 1e-4) / 0.3) - min_jerk((t_f - 0.2 - 1e-4) / 0.3)) / 2e-4
    assert abs(rec.finger_velocity[2] - v_true) > 0.08  # the world's lags (−0.19 of −0.30 m/s) …
    assert abs(rec.finger_fast_velocity[2] - v_true) < 0.03  # … the caps' follows
    assert rec.finger_fast[2] < rec.finger[2]  # nearer the surface the device waits on

    # the servo step hands both to the travel limiter, extrapolated to its tick in the end-effector's coordinates
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device

    servo = make_servo_step(open_device("sim", passive_object=scene.passive_object.for_mujoco()), scene)
    servo.device.reset(kinematics.ik(np.asarray(rec.X_ee)))
    seen = {}
    tick = servo.servo.tick
    servo.servo.tick = lambda *a, **k: (seen.update(k), tick(*a, **k))
    t = rec.finger_t + 0.01
    servo.tick(t, rec)
    world_state, fast_state = seen["finger"]
    for got, p, v in ((world_state, rec.finger, rec.finger_velocity), (fast_state, rec.finger_fast, rec.finger_fast_velocity)):
        assert np.allclose(got, [*(np.add(p, np.multiply(v, 0.01)) - servo.mount), *v])
