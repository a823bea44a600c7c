"""The mono path: hand region and finger, hand-free background, histogram skin model, bench record."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.cli import main
from vishap.vision.background import HandFreeBackground
from vishap.vision.detector import make_detector
from vishap.vision.mono import GeometricDetector
from vishap.vision.segment import Segmenter
from vishap.vision.skin_hist import HistogramSkinModel, weak_skin_labels
from vishap.vision.skin_model import SkinModel
from vishap.vision.view import hand_region, hand_tip

from .test_fingertip_eval import GRASS, hand_image


def test_hand_region_prefers_the_region_entering_the_frame_and_finds_the_finger():
    m = np.zeros((240, 320), np.uint8)
    cv2.circle(m, (60, 60), 45, 255, -1)                  # a bigger blob that does not enter (a wall patch)
    cv2.rectangle(m, (200, 150), (260, 239), 255, -1)     # palm from the bottom edge
    cv2.rectangle(m, (220, 80), (232, 150), 255, -1)      # finger up to v = 80
    reg = hand_region(m)
    assert reg.touches_border and reg.entry_uv[1] > 230
    tip = hand_tip(reg)
    assert abs(tip[1] - 80) <= 1 and 219 <= tip[0] <= 233
    # without border contact the arm lies toward the nearer border
    m2 = np.zeros((240, 320), np.uint8)
    cv2.rectangle(m2, (250, 20), (310, 60), 255, -1)      # forearm near the right edge
    cv2.line(m2, (260, 40), (120, 140), 255, 14)           # finger towards the middle
    reg2 = hand_region(m2)
    assert not reg2.touches_border and reg2.entry_uv[0] > 250
    assert np.hypot(*(hand_tip(reg2) - (120, 140))) < 12


def test_background_is_never_learned_from_frames_with_the_hand(rng):
    seg = Segmenter(SkinModel.load())
    bg = HandFreeBackground(seg, learn_frames=3)
    hand = hand_image((300, 150), rng)
    for _ in range(4):
        bg.observe(hand, 0.0, hand_uv=np.array([300.0, 150.0]))
    assert not seg.learned and "hand in view" in bg.status
    empty = np.full_like(hand, GRASS)
    for _ in range(3):
        bg.observe(empty, 0.0, hand_uv=None)
    assert seg.learned and bg.usable and bg.status == "background"
    # the camera turns: most of the view differs from the background → skin only, said so
    moved = np.full_like(hand, (200, 230, 220))
    bg.observe(moved, 0.0, hand_uv=None)
    assert bg.moving and not bg.usable and "camera moving" in bg.status
    # still again at the new view: the old background is dropped and relearned from hand-free frames
    bg.observe(moved, 0.0, hand_uv=None)
    assert not bg.moving and not seg.learned
    for _ in range(3):
        bg.observe(moved, 0.0, hand_uv=None)
    assert seg.learned and bg.usable
    assert np.abs(seg.mean_image.astype(int) - moved).max() <= 1


def test_detector_learns_background_only_after_the_hand_leaves(rng):
    det = make_detector("geometric")
    for i in range(3):
        d = det.process(hand_image((300 + 2 * i, 150), rng), i / 30)
        assert d.found and "hand in view" in d.mode
    empty = np.full((480, 640, 3), GRASS, np.uint8)
    for i in range(3, 15):
        det.process(empty, i / 30)
    d = det.process(hand_image((310, 160), rng), 0.5)
    assert d.found and d.mode.endswith("/background")
    assert np.hypot(*(d.cap_uv - (310, 160))) < 3


def test_set_depth_uses_one_scale(rng):
    det = GeometricDetector()
    det.set_depth(0.3)
    d = det.process(hand_image((300, 150), rng), 0.0)
    assert d.found and np.hypot(*(d.cap_uv - (300, 150))) < 3
    assert d.radius_px == pytest.approx(14, abs=2.5)


def test_histogram_skin_model_fit_save_load(tmp_path, rng):
    imgs, ss, os_ = [], [], []
    for k in range(3):
        img = hand_image((300, 150), rng)
        s, o = weak_skin_labels(img.shape, (300, 150 - 14), None, (230, 136, 350, 479))
        imgs.append(img), ss.append(s), os_.append(o)
        assert s[180, 300] and not s[20, 20] and o[20, 20] and not o[300, 300]
    m = HistogramSkinModel.fit(imgs, ss, os_)
    hsv = cv2.cvtColor(np.stack([imgs[0][[200], 300], imgs[0][[20], 20]], axis=1), cv2.COLOR_BGR2HSV)
    assert m.mask_hsv(hsv).tolist() == [[255, 0]]
    path = m.save(tmp_path / "h.npz")
    m2 = HistogramSkinModel.load(path)
    assert m2.mask_hsv(hsv).tolist() == [[255, 0]] and m2.threshold == m.threshold
    (tmp_path / "bad.npz").write_bytes(b"junk")
    with pytest.raises(ConfigError, match="bad.npz"):
        HistogramSkinModel.load(tmp_path / "bad.npz")
    assert HistogramSkinModel.load().bins == (30, 32, 16)  # the shipped table


def test_bench_vision_real_records_real_and_synthetic(tmp_path, rng):
    from vishap.vision.toy import write_sequence

    real = tmp_path / "real"
    (real / "images").mkdir(parents=True)
    rows = ["frame,u,v,thumb_u,thumb_v,box_x0,box_y0,box_x1,box_y1"]
    for k, uv in enumerate([(300, 150), (250, 170), (350, 140), (320, 160)], start=1):
        name = f"IMG_{k:04d}.png"
        cv2.imwrite(str(real / "images" / name), hand_image(uv, rng))
        rows.append(f"{name},{uv[0]},{uv[1]},,,{uv[0] - 80},{uv[1] - 20},{uv[0] + 60},479")
    (real / "labels.csv").write_text("\n".join(rows) + "\n")
    write_sequence(tmp_path / "toy", seed=3, frames=16, learn=4)
    out = tmp_path / "out"
    assert main(["bench", "vision_real", "--data", str(real), "--synth", str(tmp_path / "toy"), "--fit-last", "2",
                 "--detectors", "", "--out", str(out)]) == 0
    rec = json.loads((out / "vision_real.json").read_text())
    geo = rec["variants"]["geometric (improved)"]
    assert geo["real"]["frames"] == 4 and geo["real_fit"]["frames"] == 2 and geo["real_held_out"]["frames"] == 2
    assert geo["real"]["pck_10"] == 1.0
    assert geo["synthetic"]["frames"] == 12 and geo["synthetic"]["hidden_frames"] == 4
    assert "paper (as shipped)" in rec["variants"] and "spearman_rho" in rec["synthetic_predicts_real"]
    assert (out / "vision_real_speed_accuracy.png").is_file()
    # the shipped histogram is reproducible by the command (here on the first two photos)
    assert main(["skin", "fit-real", str(real / "images"), "--labels", str(real / "labels.csv"), "--first", "2",
                 "--out", str(tmp_path / "s.npz")]) == 0
    assert "2 photos" in HistogramSkinModel.load(tmp_path / "s.npz").source


def test_stereo_pipeline_says_when_its_background_holds_the_hand(ideal_rig):
    from vishap.vision.pipeline import VisionPipeline
    from vishap.vision.toy import ToyScene

    scene = ToyScene(ideal_rig, seed=2)
    tip = np.array([0.0, 0.02, 0.55])
    empty = [scene.frame(i / 30, tip, hand=False) for i in range(4)]
    with_hand = [scene.frame(i / 30, tip, hand=True) for i in range(4)]
    pipe = VisionPipeline(ideal_rig)
    pipe.learn_background(empty)
    assert pipe.background_warning == ""
    pipe.learn_background(with_hand)
    assert "hand in view" in pipe.background_warning
    est = pipe.process(with_hand[0])  # the hand is the background now: nothing is found, and it says why
    assert not est.found and "learn the background again" in est.reason
