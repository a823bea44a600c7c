import numpy as np
import pytest

from vishap.tactile.classifier import ContactClassifier, ContactState, ThresholdClassifier, classify_features
from vishap.tactile.config import load_tactile_config
from vishap.tactile.examples import make_tracker, run_worked_examples
from vishap.tactile.sensor import SensorArray, SensorFrame
from vishap.tactile.sequences import PatchTrack, frames, labelled_sequence

CFG = load_tactile_config()
ARRAY = SensorArray(CFG.sensor)


def test_hertz_patch_carries_the_force_and_is_centred():
    p = ARRAY.pressure([0.0412, 0.0013], [0.005, 0.004], 0.8)
    assert p.sum() * ARRAY.element_area_m2 == pytest.approx(0.8, rel=0.02)
    cx = (p * ARRAY.x_m).sum() / p.sum()
    cy = (p * ARRAY.y_m).sum() / p.sum()
    assert cx == pytest.approx(0.0412, abs=2e-4) and cy == pytest.approx(0.0013, abs=2e-4)
    assert not ARRAY.pressure([0.04, 0.0], 0.004, 0.0).any()


def _run(track, rng=None, noise=None):
    tr, clf = make_tracker(CFG, ARRAY), ContactClassifier(CFG.classifier)
    out = []
    for fr in frames(track, ARRAY, rng=rng, noise_pa=noise):
        f = tr.update(fr)
        out.append((f, clf.update(f)))
    return out


def test_features_speed_and_pulses_of_a_sweep():
    t = np.arange(0.0, 0.2, 1e-3)
    x = 0.07 - 0.2 * t  # 20 cm/s along -x
    track = PatchTrack(t, np.column_stack([x, np.zeros_like(t)]), np.full((len(t), 2), 0.004),
                       np.full(len(t), 0.4))
    f, state = _run(track)[-1]
    assert f.centroid_velocity_m_s[0] == pytest.approx(-0.2, rel=0.03)
    # an element stays engaged for about the patch length / speed (< 100 ms)
    assert 0.01 < f.pulse_s < 0.06
    assert state == ContactState.SLIP


@pytest.mark.parametrize("seed", [0, 1])
def test_paper_worked_examples(seed):
    rec = run_worked_examples(CFG, seed=seed)
    assert rec["all_correct"], {k: rec[k]["state"] for k in ("concentrated", "distributed", "slip")}
    c, d, s = rec["concentrated"], rec["distributed"], rec["slip"]
    assert c["measured"]["centroid_cm"][1] == pytest.approx(3.5, abs=0.1)
    assert c["measured"]["force_n"] == pytest.approx(0.65, abs=0.03)
    # paper: 8 elements, 0.5 cm² (noise can flip the corner elements that sit at the threshold)
    assert 7 <= c["measured"]["engaged"][1] <= 10 and c["measured"]["area_cm2"][1] == pytest.approx(0.5, abs=0.15)
    assert 17 <= d["measured"]["engaged"][1] <= 24 and d["measured"]["force_n"] == pytest.approx(0.48, abs=0.03)
    assert d["measured"]["broad_for_ms"] > 250
    assert s["measured"]["centroid_cm"][0] == pytest.approx(6.5, abs=0.1)
    assert s["measured"]["centroid_cm"][1] == pytest.approx(3.9, abs=0.1)
    assert s["measured"]["pulse_ms"] < 100
    # the regional parameters that follow (paper §3.2–3.4)
    assert [r["gamma"] for r in c["regions"]] == [1.8, 0.7, 0.4]
    assert d["regions"][1]["gamma"] == 1.5 and d["regions"][1]["beta_hz"] == 120
    assert s["regions"][2]["gamma"] == 1.7 and s["regions"][2]["beta_hz"] == 280
    assert s["regions"][2]["phi_over_pi"] == pytest.approx(0.9)


def test_labelled_noisy_sequences_reach_95_percent():
    rng = np.random.default_rng(7)
    ok = []
    for label in (ContactState.CONCENTRATED, ContactState.DISTRIBUTED, ContactState.SLIP):
        for _ in range(4):
            track = labelled_sequence(label, rng)
            for f, s in _run(track, rng=rng, noise=150.0):
                if f.t >= track.label_from_s:
                    ok.append(s == label)
    assert np.mean(ok) >= 0.95


def test_rules_and_hold():
    from vishap.tactile.sensor import ContactFeatures

    c = CFG.classifier

    def feat(t, **kw):
        base = dict(t=t, in_contact=True, total_force_n=0.5, area_m2=0.5e-4, engaged=8, centroid_m=np.zeros(2),
                    peak_pa=1e4, centroid_velocity_m_s=np.zeros(2), pulse_s=0.3, force_cv=0.02, broad_for_s=0.0)
        base.update(kw)
        return ContactFeatures(**base)

    assert classify_features(feat(0, in_contact=False), c) == ContactState.NONE
    assert classify_features(feat(0), c) == ContactState.CONCENTRATED
    assert classify_features(feat(0, centroid_velocity_m_s=np.array([0.2, 0])), c) == ContactState.CONCENTRATED
    assert classify_features(feat(0, centroid_velocity_m_s=np.array([0.2, 0]), pulse_s=0.05), c) == ContactState.SLIP
    broad = dict(area_m2=1.5e-4, engaged=24)
    assert classify_features(feat(0, broad_for_s=0.2, **broad), c) == ContactState.CONCENTRATED
    assert classify_features(feat(0, broad_for_s=0.3, **broad), c) == ContactState.DISTRIBUTED
    assert classify_features(feat(0, broad_for_s=0.3, force_cv=0.4, **broad), c) == ContactState.CONCENTRATED
    firm = dict(area_m2=1.1e-4, engaged=18, total_force_n=2.0)  # 18 kPa mean: a firm fingertip press
    assert classify_features(feat(0, broad_for_s=0.5, **firm), c) == ContactState.CONCENTRATED
    clf = ContactClassifier(c)
    assert clf.update(feat(0.0)) == ContactState.CONCENTRATED  # first contact is reported at once
    fast = dict(centroid_velocity_m_s=np.array([0.3, 0]), pulse_s=0.02)
    assert clf.update(feat(0.005, **fast)) == ContactState.CONCENTRATED  # held
    assert clf.update(feat(0.005 + c.hold_s, **fast)) == ContactState.SLIP
    assert clf.update(feat(0.03, in_contact=False)) == ContactState.NONE  # release is immediate
    peer = ThresholdClassifier(c)
    assert peer.update(feat(0, centroid_velocity_m_s=np.array([0.2, 0]))) == ContactState.SLIP


def test_tracker_handles_empty_and_noise_only_frames():
    tr = make_tracker(CFG, ARRAY)
    rng = np.random.default_rng(0)
    for k in range(50):
        p = np.clip(rng.normal(0, 80, ARRAY.shape), 0, None)
        f = tr.update(SensorFrame(k * 1e-3, p))
        assert not f.in_contact and f.engaged == 0
