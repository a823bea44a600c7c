"""The learned background: averaged free pixels, never-seen pixels inpainted, fill of a region only."""
from __future__ import annotations

import numpy as np
import pytest

from vishap._core.errors import ConfigError, ShapeError
from vishap.ar import LearnedBackground, inpaint_region


def test_first_frames_are_averaged_then_followed_exponentially(rng):
    bg = LearnedBackground((8, 6), average_frames=4, rate=0.5)
    free = np.ones((6, 8), bool)
    frames = [rng.integers(0, 256, (6, 8, 3), dtype=np.uint8) for _ in range(4)]
    for f in frames:
        bg.update(f, free)
    np.testing.assert_allclose(bg.mean, np.mean(frames, axis=0), atol=1e-3)
    target = np.full((6, 8, 3), 200, np.uint8)
    before = bg.mean.copy()
    bg.update(target, free)
    np.testing.assert_allclose(bg.mean, 0.5 * before + 0.5 * 200.0, atol=1e-3)


def test_only_free_pixels_are_taken_and_unseen_ones_are_inpainted():
    bg = LearnedBackground((40, 30), average_frames=2)
    img = np.full((30, 40, 3), 90, np.uint8)
    free = np.ones((30, 40), bool)
    free[10:20, 10:20] = False
    bg.update(img, free)
    bg.update(np.full((30, 40, 3), 250, np.uint8), np.zeros((30, 40), bool))  # nothing free: nothing taken
    assert not bg.seen[10:20, 10:20].any() and bg.seen[0, 0]
    # the hidden square never seen: filled by inpainting from its uniform surroundings
    assert np.abs(bg.image().astype(int) - 90).max() <= 3
    region = np.zeros((30, 40), np.uint8)
    region[12:18, 12:18] = 255
    frame = np.full((30, 40, 3), 7, np.uint8)
    out = bg.fill(frame, region)
    assert np.abs(out[12:18, 12:18].astype(int) - 90).max() <= 3
    assert (out[region == 0] == 7).all()


def test_a_pixel_seen_later_takes_that_frame_at_once():
    bg = LearnedBackground((20, 20), average_frames=10, rate=0.01)
    hidden = np.ones((20, 20), bool)
    hidden[5:10, 5:10] = False
    bg.update(np.full((20, 20, 3), 50, np.uint8), hidden)
    bg.image()
    bg.update(np.full((20, 20, 3), 180, np.uint8), ~hidden)
    assert (bg.image()[5:10, 5:10] == 180).all() and (bg.image()[0, 0] == 50).all()


def test_inpaint_region_touches_only_the_region(rng):
    img = rng.integers(0, 256, (50, 60, 3), dtype=np.uint8)
    region = np.zeros((50, 60), np.uint8)
    region[20:30, 25:35] = 255
    for method in ("telea", "ns"):
        out = inpaint_region(img, region, method=method)
        assert (out[region == 0] == img[region == 0]).all()
        assert not (out[region > 0] == img[region > 0]).all()


def test_bad_input():
    bg = LearnedBackground((8, 6))
    with pytest.raises(ShapeError, match="uint8"):
        bg.update(np.zeros((6, 8, 3), np.float32), np.ones((6, 8), bool))
    with pytest.raises(ConfigError, match="inpainting"):
        LearnedBackground((8, 6), inpaint="magic")
