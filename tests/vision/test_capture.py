import cv2
import numpy as np
import pytest

from vishap import VisionError
from vishap.vision.capture import ArraySource, SideBySideVideoSource, VideoPairSource, check_pair, open_source


def _write_video(path, frames, fps=30.0):
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    assert vw.isOpened()
    for f in frames:
        vw.write(f)
    vw.release()


def _frames(n, w=64, h=48, base=0):
    return [np.full((h, w, 3), (base + 10 * i) % 255, np.uint8) for i in range(n)]


def test_video_pair_counts_mismatched_tail(tmp_path):
    _write_video(tmp_path / "l.avi", _frames(5))
    _write_video(tmp_path / "r.avi", _frames(3, base=100))
    src = open_source(f"{tmp_path / 'l.avi'},{tmp_path / 'r.avi'}")
    assert isinstance(src, VideoPairSource)
    frames = list(src)
    assert [f.index for f in frames] == [0, 1, 2]
    assert src.stats.delivered == 3 and src.stats.mismatched == 2
    assert np.allclose([f.t for f in frames], [0, 1 / 30, 2 / 30], atol=1e-3)
    assert abs(int(frames[1].left.mean()) - 10) <= 2 and abs(int(frames[1].right.mean()) - 110) <= 2


def test_side_by_side_video_is_split(tmp_path):
    sbs = [np.concatenate([l, r], axis=1) for l, r in zip(_frames(4), _frames(4, base=200))]
    _write_video(tmp_path / "sbs.avi", sbs)
    src = open_source(f"sbs:{tmp_path / 'sbs.avi'}")
    assert isinstance(src, SideBySideVideoSource)
    frames = list(src)
    assert len(frames) == 4 and frames[0].left.shape == (48, 64, 3)
    assert abs(int(frames[2].right.mean()) - 220) <= 2


def test_corrupt_frames_are_dropped_or_raise():
    good = np.zeros((48, 64, 3), np.uint8)
    pairs = [
        (0.0, good, good),
        (0.1, good, np.zeros((40, 64, 3), np.uint8)),   # sizes differ: mismatched
        (0.2, np.zeros((0, 0, 3), np.uint8), good),     # empty: dropped
        (0.3, good.astype(np.float32), good),           # wrong dtype: dropped
        (0.4, np.zeros((24, 32, 3), np.uint8), np.zeros((24, 32, 3), np.uint8)),  # wrong size: dropped
        (0.5, good, None),                              # one side missing: mismatched
        (0.6, good, good),
    ]
    src = ArraySource(pairs)
    out = list(src)
    assert [f.t for f in out] == [0.0, 0.6]
    assert (src.stats.delivered, src.stats.dropped, src.stats.mismatched) == (2, 3, 2)
    strict = ArraySource(pairs, on_corrupt="raise")
    with pytest.raises(VisionError, match="frame 1: left 64×48 and right 64×40 differ"):
        list(strict)


def test_check_pair_and_bad_specs(tmp_path):
    g = np.zeros((4, 4, 3), np.uint8)
    assert check_pair(g, g) is None
    assert "expected 8×8" in check_pair(g, g, (8, 8))
    with pytest.raises(VisionError, match="not found"):
        open_source(f"{tmp_path / 'a.avi'},{tmp_path / 'b.avi'}")
    with pytest.raises(VisionError, match="not a folder"):
        open_source(tmp_path / "nothing.txt")
    (tmp_path / "junk.avi").write_bytes(b"not a video")
    with pytest.raises(VisionError, match="cannot open"):
        open_source(tmp_path / "junk.avi")
