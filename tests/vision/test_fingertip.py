import numpy as np
import pytest

from vishap.vision.fingertip import FingertipConfig, detect_fingertip, fit_circle, square_ring_offsets


def capsule(c, ang, R, shape=(160, 160), length=300.0, ss=4):
    """Anti-aliased mask of a finger whose cap centre is ``c``, pointing away from ``ang``."""
    H, W = shape
    yy, xx = (np.mgrid[0:H * ss, 0:W * ss].astype(float) + 0.5) / ss - 0.5
    d = np.array([np.cos(ang), np.sin(ang)])
    rel = np.stack([xx - c[0], yy - c[1]], -1)
    t = np.clip(rel @ d, 0, length)
    q = rel - t[..., None] * d
    cov = (np.hypot(q[..., 0], q[..., 1]) <= R).reshape(H, ss, W, ss).mean((1, 3))
    return (cov >= 0.5).astype(np.uint8) * 255


def test_ring_offsets_are_the_square_with_opposites():
    off = square_ring_offsets(3)
    assert len(off) == 24 and len({tuple(o) for o in off}) == 24
    assert np.all(np.abs(off).max(axis=1) == 3)
    assert np.array_equal(off[:12], -off[12:])


def test_fit_circle_exact():
    a = np.linspace(0, np.pi, 20)
    c, r = fit_circle(np.column_stack([3 + 5 * np.cos(a), -2 + 5 * np.sin(a)]))
    assert np.allclose(c, [3, -2]) and abs(r - 5) < 1e-9


@pytest.mark.parametrize("seed", range(6))
def test_detects_the_cap_centre_subpixel(seed):
    rng = np.random.default_rng(seed)
    c = rng.uniform(70, 90, 2)
    ang = rng.uniform(-np.pi, np.pi)
    R = rng.uniform(6.5, 10)
    tip = detect_fingertip(capsule(c, ang, R), 0.6 * R)  # the pipeline's K: 4.8 mm circle in an 8 mm cap
    assert tip.found
    assert np.hypot(*(tip.uv - c)) < 0.5
    assert np.dot(tip.direction, [np.cos(ang), np.sin(ang)]) > 0.9
    assert abs(tip.cap_radius_px - R) < 0.7


def test_middle_of_a_finger_and_a_blob_are_not_tips():
    H = W = 120
    bar = np.zeros((H, W), np.uint8)
    bar[52:68, :] = 255  # a finger crossing the whole image: diagonal test rejects its middle
    assert not detect_fingertip(bar, 5.0).found
    yy, xx = np.mgrid[0:H, 0:W]
    blob = ((xx - 60) ** 2 + (yy - 60) ** 2 <= 30 ** 2).astype(np.uint8) * 255
    assert not detect_fingertip(blob, 5.0).found  # ring count too large everywhere
    assert not detect_fingertip(np.zeros((H, W), np.uint8), 5.0).found


def test_prior_breaks_ties_and_fill_ratio_variant():
    m = np.maximum(capsule((40, 40), 0.0, 8), capsule((40, 110), 0.0, 8))
    a = detect_fingertip(m, 5.0, prior_uv=(40, 40))
    b = detect_fingertip(m, 5.0, prior_uv=(40, 110))
    assert np.hypot(*(a.uv - (40, 40))) < 0.6 and np.hypot(*(b.uv - (40, 110))) < 0.6
    loose = detect_fingertip(m, 5.0, FingertipConfig(fill_ratio=0.9), prior_uv=(40, 40))
    assert loose.found and loose.n_candidates >= a.n_candidates


def test_nearest_first_search_gives_the_full_search_result():
    """A tracking window's search (one tip near a prior: candidates tested nearest first, no palm
    erosion) returns exactly the full search's best candidate, also beside a palm (candidates whose
    whole square is skin) and with the first valid candidate several chunks of 32 away."""
    import cv2

    import vishap.vision.fingertip as F

    m = np.maximum(capsule((40, 40), 0.3, 8), capsule((40, 112), -0.2, 8))
    palm = m.copy()
    cv2.circle(palm, (110, 110), 30, 255, -1)
    for mask, priors in ((m, ((38, 41), (44, 109), (80, 80))), (palm, ((40, 40), (112.3, 108.6), (140.5, 70.2)))):
        for prior in priors:
            fast = detect_fingertip(mask, 4.8, prior_uv=prior)
            full = F.detect_fingertips(mask, 4.8, prior_uv=prior, max_tips=2)[0]  # no shortcut with 2 tips
            assert fast.found and np.array_equal(fast.uv_pixel, full.uv_pixel) and np.array_equal(fast.uv, full.uv)
            # (the direction's sums run in another order for one tip than for two: the last bit may differ)
            assert np.allclose(fast.direction, full.direction, rtol=0, atol=1e-14)
            assert fast.cap_radius_px == full.cap_radius_px


def test_origin_gives_the_image_pixels_of_a_region():
    """A region's mask with its origin: the tips of the region plus the origin, to the last bit
    (the offsets are added as before, one after the other)."""
    import vishap.vision.fingertip as F

    m = capsule((61.3, 47.8), 0.4, 8.0)
    origin = (215, 130)
    for prior, n in (((60.0, 49.0), 1), (None, 2)):
        local = F.detect_fingertips(m, 4.8, prior_uv=prior, max_tips=n)
        image = F.detect_fingertips(m, 4.8, prior_uv=None if prior is None else np.add(prior, origin), max_tips=n,
                                    origin=origin)
        assert len(local) == len(image) >= 1
        for a, b in zip(local, image):
            assert np.array_equal(a.uv + origin, b.uv) and np.array_equal(a.uv_pixel + origin, b.uv_pixel)
            assert a.cap_radius_px == b.cap_radius_px > 0


def test_integral_image_prefilter_keeps_the_same_candidates(monkeypatch):
    """Many candidates (a hand-sized blob and fingers): the S_square prefilter changes nothing."""
    import cv2

    import vishap.vision.fingertip as F

    m = np.zeros((200, 240), np.uint8)
    cv2.circle(m, (150, 120), 45, 255, -1)  # palm
    for ang in (-2.6, -2.2, -1.8, 2.9):
        c = np.array([150 + 95 * np.cos(ang), 120 + 95 * np.sin(ang)])
        m |= capsule(c, ang + np.pi, 7.5, shape=m.shape, length=70)
    calls = []
    box_sum = F._box_sum
    monkeypatch.setattr(F, "_box_sum", lambda *a: calls.append(1) or box_sum(*a))
    cands = F.detect_fingertips(m, 4.5, max_tips=6)
    assert calls  # the prefilter ran
    monkeypatch.setattr(F, "_PREFILTER_MIN", 10 ** 9)
    plain = F.detect_fingertips(m, 4.5, max_tips=6)
    assert len(cands) == len(plain) >= 3
    for a, b in zip(cands, plain):
        assert np.array_equal(a.uv, b.uv) and a.cap_radius_px == b.cap_radius_px and a.score == b.score
