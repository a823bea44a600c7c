import numpy as np
import pytest

from vishap.tactile.config import load_tactile_config
from vishap.tactile.jnd import JNDQuantiser, jnd_changed
from vishap.tactile.phsm import band_index, phsm_targets

CFG = load_tactile_config()
FABRIC = CFG.surfaces["fabric"]


def test_texture_lines_fall_in_the_band_of_v_over_p():
    p = FABRIC.texture_period_m
    for speed, band in [(0.06, 1), (0.3, 2)]:  # 50 Hz -> texture band, 250 Hz -> fine band
        tg = phsm_targets(FABRIC, speed, 0.5, CFG.bands)
        assert len(tg) == 3 and [t.band for t in tg] == ["force", "texture", "fine"]
        assert tg[band].frequency_hz == pytest.approx(speed / p)
        assert CFG.bands[band].low_hz <= tg[band].frequency_hz <= CFG.bands[band].high_hz
    assert band_index(10, CFG.bands) == 0 and band_index(150, CFG.bands) == 1 and band_index(399, CFG.bands) == 2


def test_force_band_and_rest():
    rest = phsm_targets(FABRIC, 0.0, 0.6, CFG.bands)
    assert rest[1].amplitude == 0 and rest[2].amplitude == 0 and rest[0].amplitude > 0
    assert 0 <= rest[0].frequency_hz <= 20
    hard = CFG.surfaces["denim"].model_copy(update={"hardness": 0.9})
    soft = CFG.surfaces["denim"].model_copy(update={"hardness": 0.1})
    assert phsm_targets(hard, 0.0, 0.6, CFG.bands)[0].amplitude > phsm_targets(soft, 0.0, 0.6, CFG.bands)[0].amplitude
    rough = phsm_targets(CFG.surfaces["denim"], 0.1, 0.6, CFG.bands)
    smooth = phsm_targets(CFG.surfaces["silk"], 0.1, 0.6, CFG.bands)
    assert sum(t.amplitude for t in rough[1:]) > sum(t.amplitude for t in smooth[1:])
    for t in rough:
        assert np.isfinite([t.amplitude, t.frequency_hz, t.bandwidth_hz, t.attack_s, t.release_s]).all()
        assert 0 <= t.amplitude <= 1 and t.attack_s > 0


def test_jnd_suppresses_imperceptible_changes():
    b = CFG.bands[1]
    assert not jnd_changed(0.50, 100, 0.52, 100, b)
    assert jnd_changed(0.50, 100, 0.60, 100, b)
    assert jnd_changed(0.50, 130, 0.50, 100, b)
    assert jnd_changed(0.5, 100, 0.0, 100, b) and jnd_changed(0.0, 100, 0.5, 100, b)
    assert not jnd_changed(0.001, 100, 0.0, 300, b)  # both below detection
    q = JNDQuantiser(CFG.bands)
    amps = 0.5 + 0.01 * np.sin(np.linspace(0, 6, 200))
    sent = [q.update([a, a, a], [10, 100, 300]).any() for a in amps]
    assert sum(sent) == 1 and q.saved_fraction > 0.99
    assert q.changed == 3 * 200 and q.saved_vs_change_only == pytest.approx(1 - 3 / 600)
    assert q.update([0.9, 0.9, 0.9], [10, 100, 300]).all()
