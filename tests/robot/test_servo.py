"""The servo cycle and the X_d gap policies."""
import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.robot.controller import Controller, Gains
from vishap.robot.plant import MujocoPlant
from vishap.robot.servo import ServoLoop, TargetShaper


def test_policies_between_samples():
    sh = {p: TargetShaper(p) for p in ("hold", "interpolate", "extrapolate")}
    for s in sh.values():
        s.push(0.00, 0.0, 0.0, 0.0)
        s.push(0.05, 0.05, 0.0, 0.0)  # 1 m/s along x, 20 Hz
    t = 0.05 + 0.02
    assert sh["hold"].at(t)[:4] == (0.05, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(sh["interpolate"].at(t)[:4], (0.02, 0.0, 0.0, 1.0))
    np.testing.assert_allclose(sh["extrapolate"].at(t)[:4], (0.07, 0.0, 0.0, 1.0))
    # after one interval interpolation has arrived; extrapolation stops at the horizon (1.5 intervals)
    np.testing.assert_allclose(sh["interpolate"].at(0.2)[:4], (0.05, 0.0, 0.0, 0.0))
    np.testing.assert_allclose(sh["extrapolate"].at(0.2)[:4], (0.05 + 0.075, 0.0, 0.0, 0.0))


def test_new_sample_detection():
    s = TargetShaper("hold")
    s.offer(0.0, (0.1, 0.0, 0.0))
    s.offer(0.001, (0.1, 0.0, 0.0))
    assert s.n_samples == 1
    s.offer(0.002, (0.1, 0.0, 0.0), t_sample=0.002)
    assert s.n_samples == 2


def test_unknown_policy_refused():
    with pytest.raises(ConfigError, match="policy"):
        TargetShaper("blend")


@pytest.mark.parametrize("policy", ["hold", "interpolate", "extrapolate"])
def test_servo_follows_vision_rate_target(policy):
    plant = MujocoPlant(passive_object=demo_passive_object())
    servo = ServoLoop(plant, Controller(plant.params, Gains(), limits=plant.limits), policy=policy)
    X = np.array([0.215, 0.0, -0.17])
    for i in range(2000):
        t = i * 1e-3
        if i % 33 == 0:  # 30 Hz vision
            X = np.array([0.215, 0.03 * min(t, 1.0), -0.17 + 0.05 * min(t, 1.0)])
        servo.tick(t, X)
    assert np.linalg.norm(plant.read().p_robot - X) < 1e-3


def test_holds_position_before_any_target_and_adds_the_extra_force():
    plant = MujocoPlant(passive_object=demo_passive_object(), q0=[0.1, 0.2, 0.1])
    servo = ServoLoop(plant, Controller(plant.params, Gains(), limits=plant.limits))
    p0 = plant.read().p_robot
    for i in range(600):
        servo.tick(i * 1e-3)
    assert np.linalg.norm(plant.read().p_robot - p0) < 1e-6
    for i in range(600, 1600):
        servo.tick(i * 1e-3, None, np.array([0.0, 0.0, 0.5]))
    # a constant 0.5 N push against Kp moves it 0.5 / Kp up, give or take what the Coulomb friction holds
    # (0.03-0.06 N along an axis: test_coulomb_friction_at_the_tip_is_about_the_data_sheet_figure)
    kp = Gains().kp
    assert plant.read().p_robot[2] - p0[2] == pytest.approx(0.5 / kp, abs=0.06 / kp)


from hypothesis import given, settings, strategies as st  # noqa: E402
from vishap.world.scene import demo_passive_object

garbage = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e308, -1e308, 0.0]))


@settings(max_examples=40, deadline=None)
@given(
    targets=st.lists(st.lists(garbage, min_size=3, max_size=3), min_size=1, max_size=6),
    forces=st.lists(st.lists(garbage, min_size=3, max_size=3), min_size=1, max_size=6),
    policy=st.sampled_from(["hold", "interpolate", "extrapolate"]),
)
def test_servo_never_writes_nan_or_over_limit(targets, forces, policy):
    """Whatever X_d and extra force arrive, every torque written to the device is finite and bounded."""
    plant = MujocoPlant(passive_object=demo_passive_object())
    written = []
    write = plant.command_torque_scalar

    def spy(a, b, c):
        written.append((a, b, c))
        write(a, b, c)

    plant.command_torque_scalar = spy
    servo = ServoLoop(plant, Controller(plant.params, Gains(ramp_s=0.0), limits=plant.limits), policy=policy)
    lim = plant.limits.max_torque_nm
    for i in range(24):
        servo.tick(i * 1e-3, targets[i % len(targets)], forces[i % len(forces)])
        assert np.linalg.norm(servo.controller.F_cmd) <= plant.limits.peak_force_n * (1 + 1e-12)
    assert len(written) == 24
    assert np.all(np.isfinite(written)) and np.max(np.abs(written)) <= lim
    assert np.all(np.isfinite(plant.read().q))
