import numpy as np
import pytest

from vishap import ShapeError, VisionError
from vishap.vision.rig import StereoRig
from vishap.vision.segment import (
    SegmentConfig,
    Segmenter,
    histogram_intersection,
    hue_bin_image,
    snap_roi,
    tile_histograms,
)
from vishap.vision.skin_model import SkinModel
from vishap.vision.toy import ToyScene


def test_tile_histograms_match_a_loop_over_tiles(rng):
    b = rng.integers(0, 9, (23, 31)).astype(np.uint8)  # partial tiles at the right/bottom
    hist = tile_histograms(b, 5, 9)
    assert hist.shape == (5, 7, 9)
    for ty in range(5):
        for tx in range(7):
            tile = b[ty * 5:(ty + 1) * 5, tx * 5:(tx + 1) * 5]
            assert np.array_equal(hist[ty, tx], np.bincount(tile.ravel(), minlength=9))


def test_histogram_intersection_is_eq1():
    I = np.array([[3, 0, 2], [0, 0, 0]])
    M = np.array([[1, 2, 2], [0, 0, 0]])
    assert histogram_intersection(I, M).tolist() == [3 / 5, 1.0]


def test_hue_bins_and_achromatic_bin():
    hsv = np.array([[[0, 200, 200], [179, 200, 200], [90, 10, 200], [45, 200, 5]]], np.uint8)
    b = hue_bin_image(hsv, SegmentConfig(bins=8))
    assert b.tolist() == [[0, 7, 8, 8]]
    assert hue_bin_image(hsv, SegmentConfig(bins=8, achromatic_bin=False)).tolist() == [[0, 7, 4, 2]]


def test_snap_roi_widens_to_tiles_and_clips():
    assert snap_roi((3, 7, 21, 22), 5, (640, 480)) == (0, 5, 25, 25)
    assert snap_roi((-10, -3, 700, 500), 5, (640, 480)) == (0, 0, 640, 480)


@pytest.fixture(scope="module")
def toy():
    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    scene = ToyScene(rig, seed=3)
    bg = [scene.frame(0.0, (0, 0, 0.5), hand=False) for _ in range(5)]
    fr = scene.frame(0.1, (0.01, 0.0, 0.5), light=0.85, device_cam=[[-0.1, 0.08, 0.6], [-0.02, 0.05, 0.6]])
    skin = SkinModel.fit([fr.left], [fr.labels_left])
    return bg, fr, skin


def test_segmentation_of_a_toy_frame_matches_labels(toy):
    bg, fr, skin = toy
    seg = Segmenter(skin)
    seg.learn([f.left for f in bg])
    mask = seg.segment(fr.left) > 0
    gt = fr.labels_left == 1
    assert gt.sum() > 500
    assert np.mean(mask == gt) > 0.995
    assert np.mean(mask & ~gt) < 0.005  # the grey arm (moved in after learning) is not skin


def test_roi_segmentation_equals_the_full_frame_inside(toy):
    bg, fr, skin = toy
    seg = Segmenter(skin, SegmentConfig(median=1))
    seg.learn([f.left for f in bg])
    full = seg.segment(fr.left)
    roi = snap_roi((100, 60, 200, 170), 5, (320, 240))
    part = seg.segment(fr.left, roi)
    x0, y0, x1, y1 = roi
    assert np.array_equal(part[5:-5, 5:-5], full[y0:y1, x0:x1][5:-5, 5:-5])  # away from dilation borders


def test_segment_errors(toy):
    bg, fr, skin = toy
    seg = Segmenter(skin)
    with pytest.raises(VisionError, match="before learn"):
        seg.segment(fr.left)
    seg.learn([bg[0].left])
    with pytest.raises(ShapeError, match="expected size 320×240"):
        seg.segment(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(ShapeError, match="uint8 BGR"):
        seg.segment(np.zeros((240, 320), np.uint8))
    with pytest.raises(VisionError, match="odd"):
        SegmentConfig(median=4)


@pytest.mark.parametrize("cfg", [SegmentConfig(), SegmentConfig(dilate_tiles=0, median=3), SegmentConfig(bins=16, achromatic_bin=False),
                                 SegmentConfig(bins=16, sat_bins=4)])
def test_sparse_tiles_give_exactly_the_dense_mask(toy, cfg):
    bg, fr, skin = toy
    seg = Segmenter(skin, cfg)
    seg.learn([f.left for f in bg])
    for roi in (None, (60, 40, 260, 200)):
        a = seg.segment(fr.left, roi, method="sparse")
        b = seg.segment(fr.left, roi, method="dense")
        assert a.any() and np.array_equal(a, b)


def test_hue_and_gate_read_as_one_index_give_the_same_mask(toy):
    """The hue-interval skin test reads its table and the histogram bins at ``hue | not chromatic``:
    the same masks as the hue table and the gate applied apart (dense window and sparse frame)."""
    bg, fr, skin = toy
    fast = Segmenter(skin)
    plain = Segmenter(skin)
    plain._skin_v = plain._bin_v = None
    for seg in (fast, plain):
        seg.learn([f.left for f in bg])
    assert fast._skin_v is not None
    for roi in (None, (150, 100, 220, 170), (60, 40, 260, 200)):
        a, b = fast.segment(fr.left, roi), plain.segment(fr.left, roi)
        assert a.any() and np.array_equal(a, b)


@pytest.mark.parametrize("coarse", [2, 4])
def test_coarse_skin_pass_gives_the_same_mask(toy, coarse):
    import cv2

    """The coarse pass segments only around skin found on a subsampled image: the same mask as the
    plain path over the whole frame, on a frame with the hand and the arm and on one with scattered skin-hued specks
    (lone samples start no region, but a speck beside the hand is kept by the full-resolution pass)."""
    bg, fr, skin = toy
    plain = Segmenter(skin, SegmentConfig(coarse_min_px=0))
    fast = Segmenter(skin, SegmentConfig(coarse=coarse, coarse_min_px=0))
    for seg in (plain, fast):
        seg.learn([f.left for f in bg])
    specks = fr.left.copy()
    ys, xs = np.random.default_rng(0).integers(0, 240, 40), np.random.default_rng(1).integers(0, 320, 40)
    specks[ys, xs] = (120, 150, 215)  # single skin-coloured pixels: removed by the median either way
    for img in (fr.left, specks):
        a, b = plain.segment(img), fast.segment(img)
        assert a.any() and np.array_equal(a, b)
        for roi in ((60, 40, 263, 203), (0, 0, 170, 120), (150, 100, 320, 240)):  # regions that cut the hand
            # a region's edge can leave a sliver of skin narrower than two samples, which the coarse
            # pass does not see; nothing a fingertip's test circle (radius ≥ 4 px) fits in is lost
            a, b = plain.segment(img, roi), fast.segment(img, roi)
            disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9))
            assert a.shape == b.shape and np.array_equal(cv2.erode(a, disk), cv2.erode(b, disk))
            assert np.count_nonzero(b & ~a) == 0  # it never adds skin
    assert not fast.segment(bg[0].left).any()  # nothing skin-like: no box at all
    with pytest.raises(VisionError, match="coarse"):
        SegmentConfig(coarse=0)


@pytest.mark.parametrize("cfg", [SegmentConfig(), SegmentConfig(bins=16, sat_bins=4, median=3, dilate_tiles=0)])
def test_torch_batch_backend_gives_the_same_masks(toy, cfg):
    pytest.importorskip("kornia")
    import cv2

    from vishap.vision.segment_torch import TorchSegmenter

    bg, fr, skin = toy
    seg = Segmenter(skin, cfg)
    seg.learn([f.left for f in bg])
    frames = [fr.left, fr.right, bg[0].left]
    ref = np.stack([seg.segment(f) for f in frames])
    hsv = np.stack([cv2.cvtColor(f, cv2.COLOR_BGR2HSV) for f in frames])
    got = TorchSegmenter(skin, seg.config, seg.background).segment(hsv)
    assert ref[0].any() and got.shape == ref.shape and np.array_equal(got, ref)


@pytest.mark.parametrize("k", [3, 5, 7])
def test_binary_median_is_opencvs_median_of_a_mask(k):
    import cv2

    from vishap.vision.segment import binary_median

    rng = np.random.default_rng(k)
    m = (cv2.GaussianBlur(rng.random((61, 83)).astype(np.float32), (0, 0), 3) > 0.5).astype(np.uint8) * 255
    m[rng.random(m.shape) < 0.05] ^= 255  # speckle, and skin on the border
    assert np.array_equal(binary_median(m, k), cv2.medianBlur(m, k))


@pytest.mark.parametrize("k", [3, 5, 7, 9])
def test_median_in_place_of_a_view_is_opencvs_median(k):
    """The segmentation's median writes into a box of the mask (a view): the same pixels as
    medianBlur of that box, nothing outside it touched."""
    import cv2

    from vishap.vision.segment import _median_in_place

    rng = np.random.default_rng(10 + k)
    m = (cv2.GaussianBlur(rng.random((70, 90)).astype(np.float32), (0, 0), 3) > 0.5).astype(np.uint8) * 255
    m[rng.random(m.shape) < 0.05] ^= 255
    box = (slice(5, 61), slice(7, 80))
    want = m.copy()
    want[box] = cv2.medianBlur(np.ascontiguousarray(m[box]), k)
    _median_in_place(m[box], k)
    assert np.array_equal(m, want)


def test_coarse_samples_are_the_strided_pixels():
    """The coarse pass samples a region by a nearest-neighbour resize where its size is a multiple
    of the step: exactly the pixels of the strided slice."""
    import cv2

    rng = np.random.default_rng(4)
    img = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    for k in (2, 3, 4, 5):
        for x0, y0, w, h in ((0, 0, 640, 480), (35, 20, 300, 240), (5, 10, 60 * k, 45 * k)):
            sub = img[y0:y0 + h, x0:x0 + w]
            if w % k or h % k:
                continue
            got = cv2.resize(sub, (w // k, h // k), interpolation=cv2.INTER_NEAREST)
            assert np.array_equal(got, sub[::k, ::k]), (k, x0, y0, w, h)
