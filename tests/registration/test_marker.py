import cv2
import numpy as np
import pytest

from vishap.registration.marker import detect_marker


def _sphere_image(centre, radius, *, size=(160, 120), ss=5, light=(-0.5, -0.5, 0.7), highlight=True, rng=None,
                  occluder=None):
    """A shaded green sphere (Lambert + a white Blinn highlight) drawn at ``ss``× and averaged down (anti-aliased)."""
    w, h = size
    W, H = w * ss, h * ss
    yy, xx = np.mgrid[0:H, 0:W]
    # pixel centres of the small image: (x + 0.5) / ss - 0.5
    u = (xx + 0.5) / ss - 0.5
    v = (yy + 0.5) / ss - 0.5
    dx, dy = (u - centre[0]) / radius, (v - centre[1]) / radius
    r2 = dx * dx + dy * dy
    inside = r2 <= 1.0
    nz = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0))
    L = np.asarray(light, float) / np.linalg.norm(light)
    lam = np.clip(dx * L[0] + dy * L[1] + nz * L[2], 0.0, 1.0)
    img = np.zeros((H, W, 3), np.float32)
    img[:] = (110, 120, 125)  # grey table
    if rng is not None:
        img += rng.normal(0, 3, size=(H // ss, W // ss, 1)).repeat(ss, 0).repeat(ss, 1)
    sphere = np.zeros((H, W, 3), np.float32)
    sphere[..., 1] = 40 + 215 * lam
    if highlight:
        Hv = (L + [0.0, 0.0, 1.0]) / np.linalg.norm(L + [0.0, 0.0, 1.0])  # Blinn half-vector, viewer on +z
        spec = np.clip(dx * Hv[0] + dy * Hv[1] + nz * Hv[2], 0, 1) ** 60 * 255
        sphere += spec[..., None]
    img = np.where(inside[..., None], np.clip(sphere, 0, 255), img)
    if occluder is not None:
        x0, y0, x1, y1 = (int(c * ss) for c in occluder)
        img[y0:y1, x0:x1] = (30, 30, 30)
    small = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    return np.clip(np.round(small), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("radius", [2.5, 4.0, 7.0])
def test_sub_pixel_centre(rng, radius):
    errs = []
    for _ in range(6):
        c = rng.uniform([30, 30], [130, 90])
        det = detect_marker(_sphere_image(c, radius, rng=rng, light=rng.normal(size=3) * [1, 1, 0] + [0, 0, 1.2]))
        assert det, det.reason
        errs.append(np.linalg.norm(det.uv - c))
        assert det.radius_px == pytest.approx(radius, rel=0.15)
    # a harsh model (no ambient light: a hard terminator, a strong highlight) — still sub-pixel
    assert np.max(errs) < 0.2, errs
    assert np.mean(errs) < 0.12, errs


def test_no_marker_border_and_occlusion_are_rejected(rng):
    grey = np.full((120, 160, 3), 120, np.uint8)
    assert not detect_marker(grey)
    assert "no green" in detect_marker(grey).reason
    cut = detect_marker(_sphere_image((2.0, 60.0), 5.0))
    assert not cut and "border" in cut.reason
    hidden = detect_marker(_sphere_image((80.0, 60.0), 6.0, occluder=(80.0, 0.0, 160.0, 120.0)))
    assert not hidden and "hidden" in hidden.reason
    # a larger green-ish distractor with little saturation does not win over the marker
    img = _sphere_image((50.0, 60.0), 4.0)
    img[10:40, 100:150] = (100, 140, 100)  # pale green patch (greenness 0.16, below threshold)
    det = detect_marker(img)
    assert det and np.linalg.norm(det.uv - [50.0, 60.0]) < 0.1
