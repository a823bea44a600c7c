"""The hybrid detector: learned find + geometric refine on real photos, window tracking on a moving
real image (needs the [learned] extra's runtime; skipped without it)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.vision.hybrid import HybridConfig, HybridDetector, LocalSkin

from .test_learned import real_photo

pytest.importorskip("ai_edge_litert")


@pytest.fixture(scope="module")
def model():
    from vishap.vision.learned import HandLandmarkModel

    return HandLandmarkModel()


def hybrid(model, **options) -> HybridDetector:
    from vishap.vision.learned import LearnedConfig, LearnedDetector

    return HybridDetector(HybridConfig(**options), learned=LearnedDetector(LearnedConfig(mode="video"), model=model))


def test_bad_options_are_one_clear_error():
    with pytest.raises(ConfigError, match="skin"):
        HybridConfig(skin="rgb")
    with pytest.raises(ConfigError, match="cut_ncc"):
        HybridConfig(cut_ncc=1.5)


@pytest.mark.parametrize("name", ["TI1K_IMAGE_0201.jpg", "TI1K_IMAGE_0401.jpg", "TI1K_IMAGE_0701.jpg"])
def test_photo_is_found_by_the_model_and_refined_by_the_cap_fit(model, name):
    img, tip = real_photo(name)
    det = hybrid(model)
    d = det.process(img, 0.0)
    assert d.found and d.mode == "learned+refine"
    hand = det.learned.last_hand
    from vishap.vision.learned import cap_from_landmarks

    cap, r, direction = cap_from_landmarks(hand.uvz)
    # the fitted cap agrees with the landmarks' estimate (centre within the gate, similar radius)
    assert np.hypot(*(d.cap_uv - cap)) <= det.config.gate_radii * r
    assert 0.6 < d.radius_px / r < 1.6
    np.testing.assert_allclose(d.tip_end_uv, d.cap_uv - det.config.tip_end_frac * d.radius_px * d.direction)
    assert np.hypot(*(d.tip_end_uv - tip)) < 15.0          # measured: 2–7 px on these photos (cap end: 9–18)


@pytest.mark.parametrize("name", ["TI1K_IMAGE_0201.jpg", "TI1K_IMAGE_0401.jpg"])
def test_tip_end_is_where_annotators_mark_the_tip_not_the_caps_end(model, name):
    # fit-split photos: the annotation lies behind the fitted cap's end, near its centre
    img, tip = real_photo(name)
    d = hybrid(model).process(img, 0.0)
    end = hybrid(model, tip_end_frac=1.0).process(img, 0.0)
    assert d.mode == end.mode == "learned+refine"
    np.testing.assert_allclose(end.cap_uv, d.cap_uv)
    np.testing.assert_allclose(end.tip_end_uv, end.cap_uv - end.radius_px * end.direction)
    assert np.hypot(*(d.tip_end_uv - tip)) < 0.5 * np.hypot(*(end.tip_end_uv - tip))


def test_without_a_cap_fit_the_tip_lies_along_the_landmarks_cap(model):
    from vishap.vision.learned import INDEX_TIP

    img, _ = real_photo("TI1K_IMAGE_0015.jpg")   # fit split; the cap fit fails here
    det = hybrid(model)
    d = det.process(img, 0.0)
    assert d.mode == "learned"
    np.testing.assert_allclose(d.tip_end_uv, d.cap_uv - det.config.landmark_tip_end_frac * d.radius_px * d.direction)
    # None: landmark 8 itself, as the learned detector reports
    det = hybrid(model, landmark_tip_end_frac=None)
    d = det.process(img, 0.0)
    np.testing.assert_allclose(d.tip_end_uv, det.learned.last_hand.uvz[INDEX_TIP, :2], atol=1e-9)


def test_a_scene_cut_goes_to_the_learned_model_where_the_window_would_hold_a_stale_track(model):
    # photos 377 → 378 of the train order: another garden, the fingertip near the same place,
    # so the window still finds a cap within its gate
    a, _ = real_photo("TI1K_IMAGE_0377.jpg")
    b, tip = real_photo("TI1K_IMAGE_0378.jpg")
    modes, err = {}, {}
    for cut in (None, 0.5):  # the cut check alone (the re-read and the jump check would catch this pair too)
        det = hybrid(model, cut_ncc=cut, max_rereads=0, recheck_jump_radii=None)
        det.process(a, 0.0)
        d = det.process(b, 1 / 30)
        modes[cut], err[cut] = d.mode, np.hypot(*(d.cap_uv - tip))
    assert modes[None] == "tracked" and modes[0.5].startswith("learned")
    assert err[0.5] < err[None]                    # measured: 6.4 px against 13.6 px
    # a frame that only moves is no cut: it is followed in the window
    det = hybrid(model)
    det.process(a, 0.0)
    moved = cv2.warpAffine(a, np.float32([[1, 0, 4], [0, 1, -3]]), (640, 480), borderMode=cv2.BORDER_REFLECT)
    assert det.process(moved, 1 / 30).mode.startswith("tracked")


def test_local_skin_model_separates_the_finger_from_its_surroundings(model):
    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    det = hybrid(model)
    det.process(img, 0.0)
    hand = det.learned.last_hand
    skin = LocalSkin()
    assert skin.fit(img, hand, 10.0)
    mask = skin.mask(img)
    finger = hand.uv[6:8].mean(axis=0).round().astype(int)   # between PIP and DIP: inside the finger
    assert mask[finger[1], finger[0]] == 255
    # the frame's corners are background here
    assert mask[:20, :20].mean() < 64 and mask[-20:, -20:].mean() < 64


def test_window_tracking_follows_a_moving_real_image(model):
    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    det = hybrid(model, recheck_every=10)
    n, dt = 24, 1 / 30
    shifts = np.array([[2.3 * k, 6.0 * np.sin(0.25 * k)] for k in range(n)])
    caps, modes = [], []
    for k in range(n):
        m = np.float32([[1, 0, shifts[k, 0]], [0, 1, shifts[k, 1]]])
        frame = cv2.warpAffine(img, m, (640, 480), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        d = det.process(frame, k * dt)
        assert d.found
        caps.append(d.cap_uv)
        modes.append(d.mode)
    tracked = [k for k in range(n) if modes[k] == "tracked"]
    finds = [k for k in range(n) if modes[k].startswith("learned")]
    assert finds == [0, 11, 22]                    # a find, 10 tracked frames, a re-check, ...
    assert len(tracked) == n - len(finds)
    # the tracked cap moves with the image, to within a pixel
    k0 = tracked[0]
    err = [np.hypot(*((caps[k] - caps[k0]) - (shifts[k] - shifts[k0]))) for k in tracked[1:10]]
    assert np.median(err) < 1.0 and max(err) < 2.5
    # tracked frames do not run the networks
    assert det.process(cv2.warpAffine(img, np.float32([[1, 0, shifts[-1, 0] + 2], [0, 1, shifts[-1, 1]]]),
                                      (640, 480), borderMode=cv2.BORDER_REFLECT), n * dt).timings.keys() \
        == {"window_ms", "total_ms"}


def test_a_jump_out_of_the_window_hands_the_frame_back_to_the_model(model):
    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    det = hybrid(model)
    first = det.process(img, 0.0)
    jumped = cv2.warpAffine(img, np.float32([[1, 0, -90], [0, 1, 40]]), (640, 480), borderMode=cv2.BORDER_REFLECT)
    d = det.process(jumped, 1 / 30)
    assert d.found and d.mode.startswith("learned")
    np.testing.assert_allclose(d.cap_uv - first.cap_uv, [-90, 40], atol=6.0)


def test_where_the_colour_fails_the_fingertip_patch_follows(model):
    # a pale finger on a pale, textured wall: the window's skin mask breaks up, the cap fit fails
    img, _ = real_photo("TI1K_IMAGE_0891.jpg")
    det = hybrid(model, max_template_run=8, min_ncc=0.9)
    shifts = np.array([[-1.7 * k, 1.1 * k] for k in range(8)])
    dets = [det.process(cv2.warpAffine(img, np.float32([[1, 0, sx], [0, 1, sy]]), (640, 480),
                                       borderMode=cv2.BORDER_REFLECT), k / 30) for k, (sx, sy) in enumerate(shifts)]
    assert dets[0].mode == "learned"
    assert [d.mode for d in dets[1:]] == ["tracked_template"] * 7
    err = [np.hypot(*((d.cap_uv - dets[0].cap_uv) - s)) for d, s in zip(dets[1:], shifts[1:])]
    assert max(err) < 0.5
    # at most max_template_run patch-followed frames in a row, then the learned model looks again
    # (a patch that is mostly background drifts with the scene: the train video's 7-frame drift, 46 → 108 px)
    det = hybrid(model, min_ncc=0.9)
    modes = [det.process(cv2.warpAffine(img, np.float32([[1, 0, sx], [0, 1, sy]]), (640, 480),
                                        borderMode=cv2.BORDER_REFLECT), k / 30).mode for k, (sx, sy) in enumerate(shifts)]
    run = det.config.max_template_run
    assert modes[1:run + 1] == ["tracked_template"] * run and modes[run + 1].startswith("learned")
    # without the patch follower every frame goes back to the learned model
    det = hybrid(model, template=False)
    modes = [det.process(cv2.warpAffine(img, np.float32([[1, 0, sx], [0, 1, sy]]), (640, 480),
                                        borderMode=cv2.BORDER_REFLECT), k / 30).mode for k, (sx, sy) in enumerate(shifts)]
    assert all(m.startswith("learned") for m in modes)


def test_a_patch_match_off_skin_goes_back_to_the_learned_model(model):
    # the next frame tinted blue at the same grey levels (to within 6 of 255): the patch matches where it
    # was cut but nothing there is skin any more, as where a mostly-background patch follows the scene
    # instead of the finger (a plain grey frame would not do: pale skin has little saturation either)
    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)
    blue = np.clip(np.dstack([0.8 * g + 50, 0.8 * g, 0.8 * g - 19]), 0, 255).astype(np.uint8)
    modes = []
    for min_skin in (None, 0.5):
        det = hybrid(model, template_min_skin=min_skin, cut_ncc=None)
        assert det.process(img, 0.0).mode == "learned+refine"
        modes.append(det.process(blue, 1 / 30).mode)
    assert modes[0] == "tracked_template"       # without the check the patch follows
    assert modes[1].startswith("learned")       # with it the learned model looks again
    with pytest.raises(ConfigError, match="template_min_skin"):
        HybridConfig(template_min_skin=1.5)


def test_a_cap_fit_off_the_track_in_radius_position_and_direction_goes_back_to_the_learned_model(model):
    from vishap.vision.hybrid import _Fit

    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    det = hybrid(model)
    first = det.process(img, 0.0)
    assert first.mode == "learned+refine"
    r, d, pred = det._radius, det._direction.copy(), first.cap_uv.copy()
    turned = np.array([d[1], -d[0]])                       # 90° off the finger's direction
    far = pred + 2.0 * r * turned
    assert det._disagrees(_Fit(far, 0.5 * r, turned), pred)
    # any one or two of the three alone is common on good fits: kept
    assert not det._disagrees(_Fit(far, r, turned), pred)
    assert not det._disagrees(_Fit(pred + 0.5 * r * d, 0.5 * r, turned), pred)
    assert not det._disagrees(_Fit(far, 0.5 * r, d), pred)
    assert not hybrid(model, disagree_radius_ratio=None)._disagrees(_Fit(far, 0.5 * r, turned), pred)
    # in a followed frame, such a fit sends the frame to the learned model
    det._fit = lambda image, centre, radius, direction, extra_px=0.0: _Fit(centre + 2.0 * radius * turned,
                                                                          0.5 * radius, turned)
    d2 = det.process(img, 1 / 30)
    assert d2.found and d2.mode.startswith("learned")
    with pytest.raises(ConfigError, match="disagree_radius_ratio"):
        HybridConfig(disagree_radius_ratio=0.0)
    with pytest.raises(ConfigError, match="disagree_jump_radii"):
        HybridConfig(disagree_jump_radii=float("nan"))
    with pytest.raises(ConfigError, match="disagree_cos"):
        HybridConfig(disagree_cos=1.5)


def test_a_cap_fit_that_jumps_from_the_prediction_goes_back_to_the_learned_model(model):
    # the window's cap fit moved to a neighbouring cap (the thumb beside a pinching index, a knuckle):
    # same radius, same direction, but farther from the prediction than recheck_jump_radii radii
    from vishap.vision.hybrid import _Fit

    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    modes = {}
    for jump in (1.6, None):
        det = hybrid(model, recheck_jump_radii=jump)
        first = det.process(img, 0.0)
        assert first.mode == "learned+refine"
        r, d, pred = det._radius, det._direction.copy(), first.cap_uv.copy()
        side = np.array([d[1], -d[0]])
        assert not det._jumped(_Fit(pred + 1.5 * r * side, r, d), pred)
        assert det._jumped(_Fit(pred + 1.7 * r * side, r, d), pred) == (jump is not None)
        det._fit = lambda image, centre, radius, direction, extra_px=0.0: _Fit(centre + 1.7 * radius * side, radius,
                                                                              direction.copy())
        modes[jump] = det.process(img, 1 / 30).mode
    assert modes[1.6].startswith("learned") and modes[None] == "tracked"
    with pytest.raises(ConfigError, match="recheck_jump_radii"):
        HybridConfig(recheck_jump_radii=0.0)


def test_a_find_no_cap_fit_confirms_is_read_again_on_its_own_region(model):
    # fit-split photo 117: a near hand whose palm box frames it badly; the first reading puts the index tip
    # 240 px off (a curled finger), the landmark model on the region its own landmarks give finds it
    from vishap.vision.learned import roi_from_landmarks

    img, tip = real_photo("TI1K_IMAGE_0117.jpg")
    det = hybrid(model, max_rereads=0)
    once = det.process(img, 0.0)
    first_hand = det.learned.last_hand
    det = hybrid(model)
    twice = det.process(img, 0.0)
    assert once.mode == "learned"                          # no cap fit confirmed the first reading
    assert np.hypot(*(once.tip_end_uv - tip)) > 100.0      # measured 233 px
    assert np.hypot(*(twice.tip_end_uv - tip)) < 30.0      # measured 17 px
    # the second reading is the landmark model on the first reading's own region
    det = hybrid(model, max_rereads=1)
    det.process(img, 0.0)
    assert det.learned.last_hand.rect == roi_from_landmarks(first_hand.uv)
    # a find the cap fit confirms is not read again (one landmark run)
    img2, _ = real_photo("TI1K_IMAGE_0401.jpg")
    det = hybrid(model)
    calls = []
    det.learned.reread = lambda *a, **k: calls.append(1)
    assert det.process(img2, 0.0).mode == "learned+refine" and not calls


def test_a_find_whose_readings_never_settle_is_not_followed(model):
    # fit-split photo 106: the landmark model flips between a curled and a stretched index on each reading
    # (tips 24-32 cap radii apart); after max_rereads readings that never agreed the next frame is a find
    # again, where following it would track the patch of an unconfirmed cap
    img, _ = real_photo("TI1K_IMAGE_0106.jpg")
    moved = cv2.warpAffine(img, np.float32([[1, 0, 2], [0, 1, 1]]), (640, 480), borderMode=cv2.BORDER_REFLECT)
    modes, rereads = {}, {}
    for recheck in (True, False):
        det = hybrid(model, recheck_unsettled=recheck)
        calls, reread = [], det.learned.reread
        det.learned.reread = lambda *a, **k: (calls.append(1), reread(*a, **k))[1]
        assert det.process(img, 0.0).mode == "learned"
        rereads[recheck] = len(calls)
        modes[recheck] = det.process(moved, 1 / 30).mode
    assert rereads[False] == det.config.max_rereads
    assert modes[True].startswith("learned") and modes[False] == "tracked_template"
    with pytest.raises(ConfigError, match="max_rereads"):
        HybridConfig(max_rereads=-1)


def test_an_unconfirmed_find_that_agrees_with_the_track_is_not_read_again(model):
    # every cap fit failing (as on a pale finger before a pale wall), each find is unconfirmed. With no track
    # the find is read again; a re-check in a running track whose landmark cap lands within the window's
    # gate, at the track's radius, is confirmed by the track and costs no second landmark run
    img, _ = real_photo("TI1K_IMAGE_0401.jpg")
    moved = cv2.warpAffine(img, np.float32([[1, 0, 2], [0, 1, 1]]), (640, 480), borderMode=cv2.BORDER_REFLECT)
    rereads = {}
    for trust in (True, False):
        det = hybrid(model, recheck_every=1, reread_trusts_track=trust)
        det._fit = lambda *a, **k: None
        calls, reread = [], det.learned.reread
        det.learned.reread = lambda *a, **k: (calls.append(1), reread(*a, **k))[1]
        assert det.process(img, 0.0).mode == "learned" and len(calls) >= 1
        det.process(moved, 1 / 30)                         # followed: recheck_every = 1 tracked frame
        n = len(calls)
        assert det.process(img, 2 / 30).mode == "learned"  # the re-check
        rereads[trust] = len(calls) - n
    assert rereads[True] == 0 and rereads[False] >= 1
