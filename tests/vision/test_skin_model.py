import numpy as np
import pytest

from vishap import ConfigError
from vishap.vision.skin_model import SkinModel, default_skin_model_path


def _hsv_image(hues, s=150, v=180):
    hsv = np.zeros((1, len(hues), 3), np.uint8)
    hsv[0, :, 0] = hues
    hsv[0, :, 1] = s
    hsv[0, :, 2] = v
    return hsv


def test_fit_handles_the_hue_wrap():
    import cv2

    hues = np.array([176, 177, 178, 179, 0, 1, 2, 3] * 20)
    img = cv2.cvtColor(_hsv_image(hues), cv2.COLOR_HSV2BGR)
    m = SkinModel.fit([img], [np.ones(img.shape[:2], np.uint8)])
    assert abs(((m.hue_mean + 90) % 180) - 90 - (-0.5)) < 0.6
    assert m.hue_std < 3.0
    mask = m.mask_hsv(_hsv_image([178, 1, 10, 90, 170]))
    assert (mask[0] > 0).tolist() == [True, True, False, False, False]


def test_achromatic_pixels_are_never_skin():
    m = SkinModel(hue_mean=10, hue_std=4)
    assert m.mask_hsv(_hsv_image([10], s=10))[0, 0] == 0
    assert m.mask_hsv(_hsv_image([10], v=5))[0, 0] == 0
    assert m.mask_hsv(_hsv_image([10]))[0, 0] == 255


def test_interval_is_the_gaussian_threshold():
    m = SkinModel(hue_mean=20, hue_std=4, max_sigma=2.0)
    hues = np.arange(180)
    inside = m.mask_hsv(_hsv_image(hues))[0] > 0
    ll = m.log_likelihood(hues)
    thr = m.log_likelihood(20 + 8)
    assert np.array_equal(inside, ll >= thr - 1e-12)


def test_save_load_roundtrip_and_errors(tmp_path):
    m = SkinModel(hue_mean=12.5, hue_std=3.25, max_sigma=2.0, n_samples=7, source="unit")
    p = m.save(tmp_path / "skin.yaml")
    m2 = SkinModel.load(p)
    assert (m2.hue_mean, m2.hue_std, m2.max_sigma, m2.source) == (12.5, 3.25, 2.0, "unit")
    (tmp_path / "bad.yaml").write_text("hue_mean: 10\nhue_std: -1\n")
    with pytest.raises(ConfigError, match="bad.yaml.*hue_std"):
        SkinModel.load(tmp_path / "bad.yaml")
    (tmp_path / "typo.yaml").write_text("hue_mean: 10\nhue_sd: 2\n")
    with pytest.raises(ConfigError, match="typo.yaml"):
        SkinModel.load(tmp_path / "typo.yaml")


def test_shipped_default_loads():
    assert default_skin_model_path().is_file()
    m = SkinModel.load()
    assert m.n_samples > 1000 and m.source
