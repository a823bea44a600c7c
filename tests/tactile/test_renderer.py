import json
import math

import numpy as np
import pytest

from vishap.cli import main
from vishap.tactile.allocation import allocate
from vishap.tactile.classifier import ContactState
from vishap.tactile.config import load_tactile_config
from vishap.tactile.contact import ContactSample
from vishap.tactile.evaluate import false_prearms, onset_gain
from vishap.tactile.feedforward import time_to_contact
from vishap.tactile.regions import target_regions
from vishap.tactile.renderer import TactileRenderer
from vishap.tactile.scenarios import approach, from_patch_track, press, stroke, to_arrays
from vishap.tactile.sequences import worked_example
from vishap.tactile.synth import resynthesize, trace_arrays

CFG = load_tactile_config()


@pytest.fixture(scope="module")
def stroke_render():
    r = TactileRenderer(CFG)
    out = r.render(stroke(0.8, v_max_m_s=0.3))
    return r, out


def test_step_block_shapes_and_bounds(stroke_render):
    r, out = stroke_render
    b = TactileRenderer(CFG).step(ContactSample(0.0, [0, 0, 0], 0.5, [0.1, 0, 0], True))
    assert b.glove.shape == (10,) and b.regions.shape == (3, 10) and b.pins.shape == (24, 10)
    assert b.fs == 10_000
    for x in (out.glove, out.regions, out.pins):
        assert np.isfinite(x).all() and np.abs(x).max() <= 1.0
    assert out.n == 8000
    assert {s.value for s in out.state} >= {"concentrated", "slip"}


def test_corrupt_samples_give_silence_not_nan():
    r = TactileRenderer(CFG)
    for k in range(30):
        b = r.step(ContactSample(k * 1e-3, [np.nan, 0, 0], np.inf, [0, np.nan, 0], True))
        assert np.isfinite(b.pins).all() and not b.regions.any()


def test_signals_never_jump(stroke_render):
    r, out = stroke_render
    tr = trace_arrays(out.extra["trace"])
    dt = 1e-3
    step = CFG.control.amplitude_slew_per_s * dt
    assert np.abs(np.diff(tr["region_amp"], axis=0)).max() <= step + 1e-9
    assert np.abs(np.diff(tr["envelope"])).max() <= step + 1e-9
    # sample to sample a unit 400 Hz oscillator moves at most 2π·400/fs
    bound = 2 * np.pi * 400 / out.fs + step
    assert np.abs(np.diff(out.regions, axis=1)).max() <= bound
    assert np.abs(np.diff(out.pins, axis=1)).max() <= bound


def test_block_resynthesis_matches_the_tick_loop(stroke_render):
    r, out = stroke_render
    res = resynthesize(trace_arrays(out.extra["trace"]), out.fs)
    np.testing.assert_allclose(res["regions"], out.regions, atol=1e-8)
    np.testing.assert_allclose(res["pins"], out.pins, atol=2e-6)  # float32 pins
    np.testing.assert_allclose(res["glove"], out.glove, atol=1e-8)


def test_glove_stays_in_its_band_and_sleeve_above_20hz(stroke_render):
    r, out = stroke_render
    g = out.glove - out.glove.mean()
    spec = np.abs(np.fft.rfft(g)) ** 2
    f = np.fft.rfftfreq(len(g), 1 / out.fs)
    assert spec[f > 40].sum() < 0.02 * spec.sum()
    s = out.regions.sum(axis=0)
    spec = np.abs(np.fft.rfft(s)) ** 2
    f = np.fft.rfftfreq(len(s), 1 / out.fs)
    assert spec[f < 15].sum() < 0.02 * spec.sum()


def test_allocation_rules_per_state():
    rs = target_regions(ContactState.CONCENTRATED, CFG)
    amp, hz = np.array([0.3, 0.3, 0.3]), np.array([8.0, 80.0, 300.0])
    a = {s: allocate(s, 0.6, amp, hz, target_regions(s, CFG), 3.5, 0.5, CFG) for s in ContactState}
    assert a[ContactState.DISTRIBUTED].glove_support > a[ContactState.CONCENTRATED].glove_support > a[ContactState.SLIP].glove_support
    assert a[ContactState.DISTRIBUTED].sleeve_gain < a[ContactState.CONCENTRATED].sleeve_gain
    assert a[ContactState.NONE].glove_support == 0 and a[ContactState.NONE].sleeve_gain == 0
    assert allocate(ContactState.DISTRIBUTED, 0.6, amp, hz, rs, 5.0, 0.5, CFG, time_in_state_s=0.01).sleeve_gain == 0
    assert a[ContactState.CONCENTRATED].glove_osc_hz <= 20
    assert a[ContactState.CONCENTRATED].region_amp.sum() <= 1 + 1e-12


@pytest.mark.parametrize("name, slide, region, beta", [("concentrated", 0.0, 0, 320), ("distributed", 0.05, 1, 120),
                                                       ("slip", 0.22, 2, 280)])
def test_state_emphasis_follows_the_paper(name, slide, region, beta):
    r = TactileRenderer(CFG)
    track = worked_example(name)
    samples = from_patch_track(track, slide_m_s=slide)
    n_keep = 40 if name == "slip" else 100
    peak = np.zeros(3)
    for k, s in enumerate(samples):
        r.step(s)
        if k >= len(samples) - n_keep:
            peak = np.maximum(peak, r.region_amp)
    assert r.state.value == name
    assert int(np.argmax(peak)) == region
    assert r.controller.params.beta_hz[region] == pytest.approx(beta)


def test_time_to_contact():
    assert time_to_contact(0.001, -0.2, 0.0, 0.01) == pytest.approx(0.005)
    assert time_to_contact(0.003, -0.2, 0.0, 0.01) is None
    assert time_to_contact(0.001, -0.2, 50.0, 0.01) is None  # braking hard: stops short
    assert time_to_contact(0.0, 0.0, 0.0, 0.01) == 0.0
    assert time_to_contact(0.001, 0.1, 0.0, 0.01) is None


def test_feedforward_advances_onset_without_near_miss_prearms():
    g = onset_gain(CFG, speeds=(0.1, 0.2), decels=(0.0,))
    assert g["min_gain_ms"] >= 5.0
    f = false_prearms(CFG, speeds=(0.05, 0.1), stops_m=(0.001, 0.003))
    assert f["false_prearms"] == 0


def test_feedforward_prearms_predicted_slip():
    r = TactileRenderer(CFG)
    samples, tc = approach(0.1, slide_m_s=0.3)
    states = []
    slip = target_regions(ContactState.SLIP, CFG)
    for s in samples:
        r.step(s)
        if r.prearmed:
            states.append(r.effective_state)
            # the channels are readied before contact: slip parameters, no overshoot from the old set
            np.testing.assert_allclose(r.controller.params.gamma, slip.gamma)
    assert states and set(states) == {ContactState.SLIP}


def test_render_cli_writes_npz_and_wav(tmp_path, capsys):
    d = to_arrays(press(0.2))
    np.savez(tmp_path / "c.npz", **d)
    assert main(["tactile", "render", "--input", str(tmp_path / "c.npz"), "--out", str(tmp_path / "o"), "--no-plots", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["samples"] == 2000 and rec["channels"]["pins"] == 24
    from scipy.io import wavfile

    fs, w = wavfile.read(tmp_path / "o" / "drive.wav")
    assert fs == 10000 and w.shape == (2000, 5) and np.isfinite(w).all()
    with np.load(tmp_path / "o" / "drive.npz") as z:
        assert z["pins"].shape == (24, 2000)
    np.savez(tmp_path / "bad.npz", t=d["t"])
    assert main(["tactile", "render", "--input", str(tmp_path / "bad.npz"), "--out", str(tmp_path / "o2")]) == 2
    assert "missing arrays" in capsys.readouterr().err


def test_examples_cli(capsys):
    assert main(["tactile", "examples", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["all_correct"] and rec["slip"]["state"] == "slip"
    assert math.isclose(rec["distributed"]["regions"][1]["beta_hz"], 120)


def test_prearm_is_held_until_the_sensor_confirms_but_never_started_by_touch():
    from vishap.tactile.feedforward import ContactPredictor

    p = ContactPredictor(CFG.feedforward)
    # touching without any approach history: no pre-arm (purely reactive)
    assert not p.update(ContactSample(0.0, [0, 0, 0], 0.01, [0, 0, -0.1], True)).prearm
    p.reset()
    assert p.update(ContactSample(0.0, [0, 0, 0.0005], 0.0, [0, 0, -0.1], False)).prearm
    held = p.update(ContactSample(0.001, [0, 0, 0], 0.01, [0, 0, -0.1], True))
    assert held.prearm and held.time_to_contact_s == 0.0
    assert not p.update(ContactSample(0.002, [0, 0, 0], 0.1, [0, 0, 0], True), confirmed=True).prearm
    assert p.false_prearms == 0 and p.prearms == 1


def test_time_going_back_restarts_the_renderer():
    r = TactileRenderer(CFG)
    samples = press(0.2)
    for s in samples:
        r.step(s)
    b = None
    for s in samples[:60]:
        b = r.step(s)
    assert b.n == 10 and np.abs(b.regions).max() > 0


def test_contact_sample_shapes_and_the_literal_kernel():
    from vishap._core.errors import ShapeError

    with pytest.raises(ShapeError, match="position"):
        ContactSample(0.0, [0, 0], 0.1, [0, 0, 0], True)
    with pytest.raises(ShapeError, match="pad_position"):
        ContactSample(0.0, [0, 0, 0], 0.1, [0, 0, 0], True, pad_position=[1, 2, 3])
    cfg = CFG.model_copy(update={"control": CFG.control.model_copy(update={"spatial_kernel": "paper"})})
    r = TactileRenderer(cfg)
    out = r.render(press(0.2), record=False)
    # literally, R1's factor vanishes at its own centre (x = mu1) and the others take over
    assert np.abs(out.regions[0]).max() < 1e-9 and np.abs(out.regions[1:]).max() > 0


@pytest.mark.parametrize("pitch_deg, state, region", [(10, "distributed", 1), (70, "concentrated", 0)])
def test_finger_pitch_selects_pad_or_tip(pitch_deg, state, region):
    p = math.radians(pitch_deg)
    d = [math.cos(p), 0.0, -math.sin(p)]
    r = TactileRenderer(CFG)
    for k in range(450):
        t = k * 1e-3
        r.step(ContactSample(t, [0.03 * t, 0, 0], 0.48 * min(1.0, t / 0.05), [0.03, 0, 0], True, finger_dir=d))
    assert r.state.value == state
    assert int(np.argmax(r.region_amp)) == region
