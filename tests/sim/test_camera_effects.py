"""The camera model's exposure: the motion blur shortens with it, the sensor noise grows as the gain
makes up a shorter exposure's level (on plain arrays; no rendering)."""
from __future__ import annotations

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.sim.camera_effects import CameraEffects, EffectsState, apply_effects


def _noise_std(exposure_s: float, level: float = 100.0) -> float:
    fx = CameraEffects(gain=False, defocus=False, motion_blur=False, exposure_s=exposure_s)
    img = np.full((200, 200, 3), level, np.uint8)
    mask = np.zeros((200, 200), bool)
    out = apply_effects(fx, EffectsState(), {"left": img, "right": img}, {"left": mask, "right": mask},
                        {"left": None, "right": None}, 0.5, seed=3)
    return float(np.std(out["left"].astype(float)))


def test_a_shorter_exposure_is_noisier_by_the_gain_that_keeps_its_level():
    fx = CameraEffects()
    level = 100.0
    expect = lambda e: np.sqrt((e * fx.read_noise_dn) ** 2 + e * fx.shot_noise_dn * level)  # noqa: E731
    ref, short = _noise_std(0.012), _noise_std(0.004)
    assert ref == pytest.approx(expect(1.0), rel=0.05)  # the reference exposure: the noise figures as stated
    assert short == pytest.approx(expect(3.0), rel=0.05)
    assert short / ref > 2.0


def _blurred_row(exposure_s: float) -> np.ndarray:
    """A bright square on a dark ground moved 12 px to the right in one 1/30 s frame, blurred."""
    fx = CameraEffects(gain=False, defocus=False, noise=False, exposure_s=exposure_s)
    state = EffectsState()
    imgs, masks, uvs = [], [], []
    for x0 in (40, 52):
        img = np.zeros((120, 160, 3), np.uint8)
        img[40:80, x0:x0 + 40] = 200
        m = np.zeros((120, 160), bool)
        m[40:80, x0:x0 + 40] = True
        imgs.append(img), masks.append(m), uvs.append(np.array([x0 + 40.0, 60.0]))
    out = None
    for k in range(2):
        out = apply_effects(fx, state, {"left": imgs[k], "right": imgs[k]}, {"left": masks[k], "right": masks[k]},
                            {"left": uvs[k], "right": uvs[k]}, k / 30.0, seed=1)
        state.last_t = k / 30.0
        state.last_uv = dict(zip(("left", "right"), (uvs[k], uvs[k])))
    return out["left"][60, :, 0].astype(float)


def test_the_motion_blur_is_as_long_as_the_exposure():
    # the image moves 12 px per frame (360 px/s): 4.3 px in 12 ms, 1.4 px in 4 ms
    def ramp(row):  # pixels strictly between the ground and the square's level along the leading edge
        return int(np.count_nonzero((row[80:110] > 10) & (row[80:110] < 190)))
    long_, short = ramp(_blurred_row(0.012)), ramp(_blurred_row(0.004))
    assert long_ >= 3
    assert short < long_
    assert _blurred_row(0.004)[60] == pytest.approx(200.0)  # inside the square: unchanged


@pytest.mark.parametrize("bad", [0.0, -0.004, float("nan"), "4ms"])
def test_a_bad_exposure_is_refused_naming_it(bad):
    with pytest.raises(ConfigError, match="exposure_s"):
        CameraEffects(exposure_s=bad)


def test_a_sequence_refuses_an_exposure_longer_than_its_frame():
    from vishap.sim.sequence import SequenceSpec, prepare

    with pytest.raises(ConfigError, match="exposure") as e:
        SequenceSpec(scene="wall", frames=2, exposure_s=-1.0).validate()
    assert e.value.field == "exposure_s"
    with pytest.raises(ConfigError, match="longer than a frame") as e:
        prepare(SequenceSpec(scene="wall", frames=2, exposure_s=0.040))  # 30 fps: 33.3 ms per frame
    assert e.value.field == "exposure_s"
    prepare(SequenceSpec(scene="wall", frames=2, exposure_s=0.004))
