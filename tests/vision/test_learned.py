"""The learned hand-landmark detector: geometry of its graph (always) and the networks on real
photos (when the [learned] extra's runtime is installed and the real train images are beside the
repository)."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from vishap._core.errors import ConfigError, ShapeError
from vishap.vision import learned
from vishap.vision.detector import make_detector
from vishap.vision.learned import HandRect, cap_from_landmarks, roi_from_landmarks

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "real" / "ti1k-train"


def real_photo(name: str):
    """(BGR image, labelled tip end (u, v)) of one real train photo, or skip when the data is absent."""
    if not (REAL / "labels.csv").is_file():
        pytest.skip(f"real train images not found at {REAL}")
    with open(REAL / "labels.csv", newline="") as f:
        row = next(r for r in csv.DictReader(f) if r["frame"] == name)
    return cv2.imread(str(REAL / "images" / name)), np.array([float(row["u"]), float(row["v"])])


def upright_hand(scale: float = 10.0, origin=(320.0, 400.0)) -> np.ndarray:
    """21 landmarks (u, v, z) of a flat, upright right hand, fingers up (image y down)."""
    x = {0: 0.0, 1: -2.0, 2: -3.0, 3: -3.8, 4: -4.4, 5: -2.0, 9: 0.0, 13: 2.0, 17: 3.5}
    y = {0: 0.0, 1: -1.5, 2: -3.0, 3: -4.2, 4: -5.2, 5: -7.0, 9: -7.2, 13: -7.0, 17: -6.2}
    uvz = np.zeros((21, 3))
    for base in (5, 9, 13, 17):
        for k in range(4):  # MCP, PIP, DIP, TIP straight up, 2.5, 2.0, 2.1 units apart
            uvz[base + k] = (x[base], y[base] - [0.0, 2.5, 4.5, 6.6][k], 0.0)
    for k in range(5):
        uvz[k] = (x[k], y[k], 0.0)
    uvz[:, :2] = uvz[:, :2] * scale + origin
    return uvz


def test_cap_lies_one_radius_behind_the_tip_along_the_finger():
    uvz = upright_hand()
    cap, r, direction = cap_from_landmarks(uvz)
    length = np.linalg.norm(uvz[7] - uvz[8])
    assert r == pytest.approx(learned.CAP_RADIUS_PER_DISTAL * length)
    np.testing.assert_allclose(direction, [0.0, 1.0], atol=1e-12)      # into the finger: down
    np.testing.assert_allclose(cap, uvz[8, :2] + [0.0, r], atol=1e-9)


def test_a_finger_pointing_at_the_camera_keeps_its_radius_and_moves_the_cap_less():
    flat = upright_hand()
    tilted = flat.copy()
    # the distal segment turned 60° toward the camera: same 3-D length, half the image length
    d = flat[7] - flat[8]
    tilted[8] = flat[7] - np.array([d[0] * 0.5, d[1] * 0.5, -np.linalg.norm(d) * math.sin(math.radians(60))])
    cap_f, r_f, _ = cap_from_landmarks(flat)
    cap_t, r_t, _ = cap_from_landmarks(tilted)
    assert r_t == pytest.approx(r_f)
    assert np.linalg.norm(cap_t - tilted[8, :2]) == pytest.approx(0.5 * np.linalg.norm(cap_f - flat[8, :2]))


@pytest.mark.parametrize("turn_deg", [0.0, 35.0, -120.0])
def test_next_region_is_turned_with_the_hand_and_covers_it(turn_deg):
    uvz = upright_hand()
    a = math.radians(turn_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    uv = (uvz[:, :2] - uvz[0, :2]) @ rot.T + uvz[0, :2]
    rect = roi_from_landmarks(uv)
    assert math.remainder(rect.angle - a, 2 * math.pi) == pytest.approx(0.0, abs=0.05)
    # every landmark inside the square region, in the region's own frame
    q = (uv - (rect.cx, rect.cy)) @ rect.rotation()
    assert np.all(np.abs(q) < rect.size / 2)


def test_crop_and_back_projection_agree():
    img = np.zeros((480, 640, 3), np.uint8)
    cv2.circle(img, (400, 150), 3, (255, 255, 255), -1)
    rect = HandRect(380.0, 170.0, 120.0, math.radians(30))
    crop = cv2.cvtColor(rect.crop(img, 224), cv2.COLOR_BGR2GRAY).astype(np.float64)
    yy, xx = np.mgrid[0:224, 0:224]
    w = crop / crop.sum()
    q = np.array([(xx * w).sum() + 0.5, (yy * w).sum() + 0.5])  # centre of mass, continuous coordinates
    np.testing.assert_allclose(rect.to_image(q[None], 224)[0], [400.5, 150.5], atol=0.3)


def test_palm_anchor_grid_matches_the_network_output():
    assert learned._ssd_anchors(192).shape == (2016, 2)


def test_without_the_runtime_the_factories_say_how_to_install(monkeypatch):
    monkeypatch.setattr(learned, "runtime_available", lambda: False)
    for name in ("learned", "learned_video", "hybrid"):
        with pytest.raises(ConfigError, match=r"\[learned\]"):
            make_detector(name)


# ---------------------------------------------------------------------- with the runtime
@pytest.fixture(scope="module")
def model():
    pytest.importorskip("ai_edge_litert")
    return learned.HandLandmarkModel()


@pytest.mark.parametrize("name", ["TI1K_IMAGE_0201.jpg", "TI1K_IMAGE_0401.jpg", "TI1K_IMAGE_0701.jpg"])
def test_learned_finds_the_labelled_fingertip_on_a_real_photo(model, name):
    img, tip = real_photo(name)
    det = learned.LearnedDetector(model=model)
    d = det.process(img, 0.0)
    assert d.found and d.mode == "learned"
    assert np.hypot(*(d.tip_end_uv - tip)) < 20.0          # measured: 5–11 px on these photos
    assert 3.0 < d.radius_px < 40.0
    assert np.hypot(*(d.cap_uv - d.tip_end_uv)) <= d.radius_px + 1e-9
    assert {"palm_ms", "landmarks_ms", "total_ms"} <= set(d.timings)


def test_learned_reports_no_hand_on_an_empty_frame(model):
    det = learned.LearnedDetector(model=model)
    d = det.process(np.full((480, 640, 3), 128, np.uint8), 0.0)
    assert not d.found and d.tip_end_uv is None and "no hand" in d.reason


def test_video_mode_follows_the_hand_without_the_palm_detector(model):
    img, tip = real_photo("TI1K_IMAGE_0401.jpg")
    det = learned.LearnedDetector(learned.LearnedConfig(mode="video"), model=model)
    first = det.process(img, 0.0)
    shifted = cv2.warpAffine(img, np.float32([[1, 0, 6], [0, 1, -4]]), (640, 480), borderMode=cv2.BORDER_REFLECT)
    second = det.process(shifted, 1 / 30)
    assert first.found and "palm_ms" in first.timings
    assert second.found and "palm_ms" not in second.timings
    np.testing.assert_allclose(second.tip_end_uv - first.tip_end_uv, [6.0, -4.0], atol=4.0)
    det.reset()
    assert "palm_ms" in det.process(img, 2 / 30).timings


@pytest.mark.parametrize("name, mediapipe_error_px", [
    ("TI1K_IMAGE_0040.jpg", None),    # the palm cut by the lower edge: best palm box 0.08
    ("TI1K_IMAGE_0425.jpg", None),    # a large hand: its palm box at zoom 1 is a wall, presence 0.14
    ("TI1K_IMAGE_0116.jpg", 100.0),   # a fragment's box at zoom 1: the landmarks read a curled index
])
def test_hands_mediapipes_palm_rule_loses_are_recovered(model, name, mediapipe_error_px):
    """Fit-split photos (1–600) where MediaPipe's rule (best palm box ≥ 0.5, zoom 1) misses or
    takes the wrong finger; palm candidates at three zooms, verified by the landmark model's
    presence score, find the labelled tip."""
    img, tip = real_photo(name)
    before = learned.LearnedDetector(learned.LearnedConfig(**learned.MEDIAPIPE_PALM_RULE), model=model).process(img, 0.0)
    if mediapipe_error_px is None:
        assert not before.found
    else:
        assert before.found and np.hypot(*(before.tip_end_uv - tip)) > mediapipe_error_px
    det = learned.LearnedDetector(model=model)
    after = det.process(img, 0.0)
    assert after.found and np.hypot(*(after.tip_end_uv - tip)) < 20.0
    assert det.last_hand.presence >= det.config.min_presence and det.last_hand.candidate in (0, 1)


@pytest.mark.parametrize("name", ["TI1K_IMAGE_0201.jpg", "TI1K_IMAGE_0241.jpg"])
def test_weak_palm_candidates_find_no_hand_in_a_real_hand_free_scene(model, name):
    """The strip of a real photo beside the labelled hand box (no hand in it), at full frame size:
    the weaker palm boxes kept as candidates are all rejected by the presence score."""
    img, _ = real_photo(name)
    with open(REAL / "labels.csv", newline="") as f:
        row = next(r for r in csv.DictReader(f) if r["frame"] == name)
    strip = img[:, int(math.ceil(float(row["box_x1"]))) + 5:]
    scene = cv2.resize(strip, (640, 480), interpolation=cv2.INTER_LINEAR)
    weak = model.detect_palms(cv2.cvtColor(scene, cv2.COLOR_BGR2RGB), 3, min_score=0.1)
    assert weak and all(score < 0.5 for _, score in weak)      # boxes MediaPipe's rule drops
    d = learned.LearnedDetector(model=model).process(scene, 0.0)
    assert not d.found and "no hand" in d.reason


@pytest.mark.parametrize("zoom", [1.0, 1.5, 2.0])
def test_bgr_input_gives_the_networks_exactly_the_rgb_input(model, zoom):
    """The detector hands the networks the BGR frame and reorders the channels after the resize or
    crop (not on the full frame): boxes, scores and landmarks are bit for bit those of the RGB frame."""
    img, _ = real_photo("TI1K_IMAGE_0001.jpg")
    rgb = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    from_rgb = model.detect_palms(rgb, 2, min_score=0.1, zoom=zoom)
    from_bgr = model.detect_palms(img, 2, min_score=0.1, zoom=zoom, bgr=True)
    assert from_rgb and from_rgb == from_bgr
    a, b = model.landmarks(rgb, from_rgb[0][0]), model.landmarks(img, from_rgb[0][0], bgr=True)
    assert np.array_equal(a.uvz, b.uvz) and a.presence == b.presence
    # the reorder matters: the BGR frame read as RGB gives other landmarks
    assert not np.array_equal(model.landmarks(img, from_rgb[0][0]).uvz, a.uvz)


def test_a_sure_confirmed_palm_ends_the_zoom_search(model):
    """A zoom-1 box at least ``palm_sure_score`` that the landmark model confirms is taken without the
    other zooms' palm runs; without the option, or below the score, every zoom runs."""
    img, tip = real_photo("TI1K_IMAGE_0001.jpg")
    top = model.detect_palms(img, 2, min_score=0.1, bgr=True)[0][1]
    runs = []
    real = model.detect_palms

    def counted(*a, **k):
        runs.append(k.get("zoom"))
        return real(*a, **k)

    model.detect_palms = counted
    try:
        for sure, expected in ((0.0, [1.0]), (None, [1.0, 1.5, 2.0]), (min(1.0, top + 1e-6), [1.0, 1.5, 2.0])):
            runs.clear()
            d = learned.LearnedDetector(learned.LearnedConfig(palm_sure_score=sure), model=model).process(img, 0.0)
            assert runs == expected, sure
            assert d.found and np.hypot(*(d.tip_end_uv - tip)) < 20.0
    finally:
        del model.detect_palms
    with pytest.raises(ConfigError, match="palm_sure_score"):
        learned.LearnedConfig(palm_sure_score=1.5)


def test_palm_zoom_and_candidate_settings_are_checked():
    with pytest.raises(ConfigError, match="palm_zooms"):
        learned.LearnedConfig(palm_zooms=(1.0, 0.5))
    with pytest.raises(ConfigError, match="palm_candidates"):
        learned.LearnedConfig(palm_candidates=0)


def test_bad_image_is_one_clear_error(model):
    det = learned.LearnedDetector(model=model)
    with pytest.raises(ShapeError, match="uint8 BGR"):
        det.process(np.zeros((480, 640), np.float32), 0.0)


def _small_set(tmp_path, names):
    real_photo(names[0])  # skips without the real data
    (tmp_path / "images").mkdir(parents=True)
    rows = []
    with open(REAL / "labels.csv", newline="") as f:
        for r in csv.DictReader(f):
            if r["frame"] in names:
                (tmp_path / "images" / r["frame"]).write_bytes((REAL / "images" / r["frame"]).read_bytes())
                rows.append(f"{r['frame']},{r['u']},{r['v']}")
    (tmp_path / "labels.csv").write_text("frame,u,v\n" + "\n".join(rows) + "\n")
    return tmp_path


def test_bench_without_the_runtime_says_so(monkeypatch, tmp_path):
    import argparse

    from vishap.bench import learned as bench

    monkeypatch.setattr(learned, "runtime_available", lambda: False)
    rec = bench.run(argparse.Namespace(out=str(tmp_path), data=str(tmp_path)))
    assert rec["available"] is False and "[learned]" in rec["reason"]


def test_bench_scores_detectors_on_real_photos(tmp_path):
    pytest.importorskip("ai_edge_litert")
    import argparse

    from vishap.bench import learned as bench

    data = _small_set(tmp_path / "data", ["TI1K_IMAGE_0401.jpg", "TI1K_IMAGE_0402.jpg", "TI1K_IMAGE_0403.jpg"])
    args = argparse.Namespace(out=str(tmp_path / "out"), data=str(data), every=1, recheck="2",
                              moving_photos=1, moving_frames=8, fit_last=2, fit_orders="r,2")
    rec = bench.run(args)
    assert set(rec["photos"]) == {"learned", "hybrid", "hybrid_cap_end", "learned_mediapipe_palm_rule",
                                  "hybrid_no_reread_no_jump"}
    assert set(rec["video"]) == {"learned", "learned_video", "hybrid", "hybrid_recheck_2",
                                 "learned_video_mediapipe_palm_rule", "hybrid_before", "hybrid_no_cut_check",
                                 "hybrid_cap_end_no_cut_check", "hybrid_no_window_checks",
                                 "hybrid_no_reread_no_jump"}
    # the fit split (--fit-last 2: the first two photos) replayed backwards and every 2nd photo
    assert set(rec["fit_replays"]) == {"backwards", "every_2nd"}
    assert rec["fit_replays"]["backwards"]["hybrid"]["frames"] == 2
    assert rec["fit_replays"]["every_2nd"]["learned_video"]["beyond_30px"] == rec["video"]["hybrid"]["beyond_30px"] == []
    for group in ("photos", "video", "moving_photo"):
        for s in rec[group].values():
            assert s["detection_rate"] == 1.0 and s["pck_30"] == 1.0 and s["ms_per_frame"] > 0
    # the moving photo: after the first find the hybrid follows in the window, without the networks
    assert rec["moving_photo"]["hybrid"]["modes"].get("tracked", 0) >= 6
    assert rec["hybrid_over_learned_video_time"]["moving_photo_median"] < 1.0
    assert (tmp_path / "out" / "learned_speed_accuracy.png").stat().st_size > 1000
