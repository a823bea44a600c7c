"""The shipped gains file: defaults inside the measured stable region with margin; refusals."""
import pytest

from vishap._core.errors import ConfigError
from vishap.robot.controller import Gains
from vishap.robot.gains import GAINS_FILE, check_gains, load_gains
from vishap.world.scene import demo_passive_object


def test_the_code_defaults_are_the_shipped_files_gains():
    """``Gains()`` takes every field from gains.yaml (the one home of the values), as load_gains reads it."""
    from dataclasses import asdict

    import yaml

    raw = yaml.safe_load(GAINS_FILE.read_text())["gains"]
    assert asdict(Gains()) == {k: float(v) for k, v in raw.items()}
    gains, cfg = load_gains()
    assert gains == Gains()
    assert Gains(kp=600.0).kv == raw["kv"]  # a field given overrides only itself
    assert cfg.max_stiffness_n_m > 0


def test_defaults_have_margin():
    """Kp ×/÷ 2 and Kv ×/÷ 2 (all eight neighbours) and a ÷ 5 are inside the measured region."""
    gains, cfg = load_gains()
    for fk in (0.5, 1.0, 2.0):
        for fv in (0.5, 1.0, 2.0):
            check_gains(Gains(kp=gains.kp * fk, kv=gains.kv * fv, a=gains.a), cfg.stable_region)
    check_gains(Gains(kp=gains.kp, kv=gains.kv, a=gains.a / 5), cfg.stable_region)


@pytest.mark.parametrize(
    "override, field",
    [({"kp": 20000.0}, "gains"), ({"kv": 0.0}, "gains"), ({"kp": 1e6}, "gains.kp"), ({"a": 10.0}, "gains.a"),
     ({"kv": -1.0}, "gains.kv"), ({"stiffness": 1.0}, "gains.stiffness")],
)
def test_gains_outside_the_region_are_refused(override, field):
    with pytest.raises(ConfigError) as err:
        load_gains(override=override)
    assert err.value.field == field
    assert str(GAINS_FILE) in str(err.value)


def test_malformed_file_is_refused(tmp_path):
    bad = tmp_path / "gains.yaml"
    text = GAINS_FILE.read_text().replace("kp: 800.0", "kp: fast")
    bad.write_text(text)
    with pytest.raises(ConfigError, match="gains.kp"):
        load_gains(bad)
    bad.write_text(GAINS_FILE.read_text().replace("    - [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]\n", "", 1))
    with pytest.raises(ConfigError, match="stable"):
        load_gains(bad)


def test_build_servo_uses_the_file_and_refuses_unstable_gains():
    from vishap.robot import PassiveObject, build_servo

    servo = build_servo(demo_passive_object(), policy="extrapolate")
    _, cfg = load_gains()
    assert servo.controller.gains == Gains()
    assert servo.device.limits.max_stiffness_n_m == cfg.max_stiffness_n_m
    L = servo.controller.set_lambda([1.0, 1.0, 1000.0])  # λ·Kp far beyond the stable walls: clipped
    assert servo.controller.lambda_clipped and L.max() * servo.controller.gains.kp <= cfg.max_stiffness_n_m + 1e-9
    with pytest.raises(ConfigError, match="stable region"):
        build_servo(gains=Gains(kp=12800.0, kv=16.0))
