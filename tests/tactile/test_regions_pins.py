import math

import numpy as np
import pytest

from vishap.tactile.classifier import ContactState
from vishap.tactile.config import load_tactile_config
from vishap.tactile.pins import AntiAliasFilter, PinRenderer, grating_tile, nonuniformity_map, weave_tile
from vishap.tactile.regions import RegionController, preset, psi, spatial_weight, target_regions

CFG = load_tactile_config()


def test_psi_is_the_papers_formula():
    rs = preset("concentrated", CFG)
    t = np.linspace(0, 0.01, 37)
    x = 4.2
    want = sum(
        rs.alpha[i] * (1 - math.exp(-rs.lambda_per_cm[i] * abs(x - rs.mu_cm[i])))
        * np.cos(2 * np.pi * rs.beta_hz[i] * t + rs.phi_rad[i]) * rs.gamma[i]
        for i in range(3)
    )
    np.testing.assert_allclose(psi(x, t, rs), want, atol=1e-12)
    # literal kernel vanishes at a region's own centre; the decay kernel peaks there
    assert spatial_weight(3.5, rs, "paper")[0] == 0.0
    w = spatial_weight(3.5, rs, "decay")
    assert w[0] == 1.0 and np.argmax(rs.alpha * w * rs.gamma) == 0  # §3.2: emphasis on R1
    assert spatial_weight(np.array([3.5, 5.0]), rs).shape == (3, 2)


def test_control_rules():
    d = target_regions(ContactState.DISTRIBUTED, CFG)
    s = target_regions(ContactState.SLIP, CFG)
    c = target_regions(ContactState.CONCENTRATED, CFG)
    assert d.gamma[1] == 1.5 and d.beta_hz[1] == 120 and d.alpha[1] < c.alpha[1]
    assert s.gamma[2] == 1.7 and s.beta_hz[2] == 280
    assert s.phi_rad[2] == pytest.approx(c.phi_rad[2] + 0.3 * math.pi)


def test_controller_slews_without_jumps():
    ctl = RegionController(CFG)
    dt = 1e-3
    prev = ctl.params.copy()
    r = CFG.control
    for k in range(400):
        state = ContactState.SLIP if k < 200 else ContactState.DISTRIBUTED
        p = ctl.update(state, dt)
        assert np.all(np.abs(p.gamma - prev.gamma) <= r.gamma_slew_per_s * dt + 1e-12)
        assert np.all(np.abs(p.beta_hz - prev.beta_hz) <= r.beta_slew_hz_per_s * dt + 1e-9)
        assert np.all(np.abs(p.phi_rad - prev.phi_rad) <= r.phase_slew_rad_per_s * dt + 1e-12)
        prev = p.copy()
    np.testing.assert_allclose(ctl.params.gamma, target_regions(ContactState.DISTRIBUTED, CFG).gamma)


@pytest.mark.parametrize("period_m, speed", [(0.002, 0.08), (0.0012, 0.06), (0.004, 0.2), (0.0005, 0.16),
                                             (0.0008, 0.25), (0.0012, 0.3)])
def test_grating_energy_goes_to_the_nearest_channel(period_m, speed):
    pr = PinRenderer(CFG.pins, grating_tile(period_m))
    a40, a320 = pr.channel_amplitudes(0.0, speed)
    f = speed / period_m
    nearest_low = abs(math.log2(f / 40)) < abs(math.log2(f / 320))
    assert (a40 > a320) == nearest_low
    # moving along the grating's ridges produces no vibration
    assert max(pr.channel_amplitudes(math.pi / 2, speed)) < 1e-9


def test_pins_geometry_contact_area_and_force_scaling():
    rng = np.random.default_rng(0)
    pr = PinRenderer(CFG.pins, weave_tile(0.0012, roughness_rms_m=2e-6, rng=rng), umap=nonuniformity_map(CFG.pins, rng))
    assert pr.n_pins == 24
    d = np.diff(np.unique(pr.pin_pad_m[:, 0]))
    assert np.allclose(d, 0.002) and len(np.unique(pr.pin_pad_m[:, 1])) == 4
    for _ in range(300):
        pr.push_contact([0.01, 0.0], [0.1, 0.0], 0.4)
    a40, a320 = pr.update(0.0, [0.035, 0.0], [0.004, 0.003])
    inside = pr.inside([0.035, 0.0], [0.004, 0.003])
    assert 0 < inside.sum() < 24
    assert np.all(a40[~inside] == 0) and np.all(a320[~inside] == 0) and np.all(a320[inside] > 0)
    for _ in range(300):
        pr.push_contact([0.01, 0.0], [0.1, 0.0], 0.8)
    b40, b320 = pr.update(0.025, [0.035, 0.0], [0.004, 0.003])
    np.testing.assert_allclose(b320[inside], 2 * a320[inside], rtol=1e-3)  # k_F * F
    assert not pr.due(0.03) and pr.due(0.05)
    z40, z320 = pr.update(0.05, [0.035, 0.0], [0.0, 0.0])
    assert not z40.any() and not z320.any()


def test_antialias_filter_passes_slow_and_blocks_fast_motion():
    t = np.arange(0, 2.0, 1e-3)
    for f_hz, keep in [(3.0, True), (150.0, False)]:
        flt = AntiAliasFilter(20.0, 1000.0, 1)
        flt.reset([0.0])
        y = np.array([flt([np.sin(2 * np.pi * f_hz * tt)])[0] for tt in t])
        gain = np.abs(y[1000:]).max()
        assert (gain > 0.9) if keep else (gain < 0.03)
