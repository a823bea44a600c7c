"""Stereo frame sources (VisHap §2.1: "we capture real-time image pairs of the scene").

One interface over a folder written by ``vishap synth``, a recorded pair of videos, one
side-by-side video, and live cameras through ``cv2.VideoCapture`` (two devices, or one device
delivering side-by-side frames). Every source yields timestamped :class:`StereoFrame` objects and
keeps :class:`CaptureStats`: frames delivered, frames dropped (corrupt, empty or wrong size) and
frames mismatched (one side missing or of a different size than the other).

A corrupt frame is counted and skipped (``on_corrupt="drop"``, the default) or raises one
:class:`~vishap._core.errors.VisionError` that names the source and what was wrong
(``on_corrupt="raise"``) — never an error deep inside the pipeline.

``open_source(spec)`` picks the source from a string:

* a folder → synthetic sequence (``vishap synth`` output);
* ``LEFT.mp4,RIGHT.mp4`` → pair of videos; ``sbs:VIDEO`` or a single video file → side-by-side;
* ``cam:0,1`` → two cameras; ``cam:0`` or ``sbs-cam:0`` → one side-by-side camera.
"""
from __future__ import annotations

import os
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from vishap._core.errors import VisionError

__all__ = [
    "StereoFrame",
    "CaptureStats",
    "StereoSource",
    "ArraySource",
    "SynthFolderSource",
    "VideoPairSource",
    "SideBySideVideoSource",
    "CameraSource",
    "open_source",
    "check_pair",
]

_VIDEO_EXT = {".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mjpg"}


@dataclass
class StereoFrame:
    """One stereo pair: ``left``/``right`` uint8 BGR (H, W, 3), ``t`` seconds, ``index`` from the source."""

    index: int
    t: float
    left: np.ndarray
    right: np.ndarray


@dataclass
class CaptureStats:
    delivered: int = 0
    dropped: int = 0
    mismatched: int = 0
    reasons: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"delivered": self.delivered, "dropped": self.dropped, "mismatched": self.mismatched,
                "reasons": self.reasons[:20]}


def check_pair(left, right, size: tuple[int, int] | None = None) -> str | None:
    """Why a pair is unusable (``None`` when it is fine): empty, not uint8 BGR, sizes differ, wrong size."""
    for name, img in (("left", left), ("right", right)):
        if img is None:
            return f"{name} frame missing"
        if not isinstance(img, np.ndarray) or img.size == 0:
            return f"{name} frame empty"
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
            return f"{name} frame is not uint8 BGR (H, W, 3): {img.dtype} {img.shape}"
    if left.shape != right.shape:
        return f"left {left.shape[1]}×{left.shape[0]} and right {right.shape[1]}×{right.shape[0]} differ"
    if size is not None and (left.shape[1], left.shape[0]) != tuple(size):
        return f"frame {left.shape[1]}×{left.shape[0]}, expected {size[0]}×{size[1]}"
    return None


class StereoSource:
    """Base: subclasses implement ``_raw()`` yielding ``(index, t, left, right)``; this class checks
    each pair, counts drops and mismatches, and fixes the frame size from the first good pair."""

    name = "source"

    def __init__(self, *, on_corrupt: str = "drop", size: tuple[int, int] | None = None):
        if on_corrupt not in ("drop", "raise"):
            raise VisionError(f"on_corrupt: expected 'drop' or 'raise', got {on_corrupt!r}")
        self.on_corrupt = on_corrupt
        self.size = size
        self.stats = CaptureStats()

    def _raw(self) -> Iterator[tuple[int, float, object, object]]:  # pragma: no cover - abstract
        raise NotImplementedError

    def __iter__(self) -> Iterator[StereoFrame]:
        for index, t, left, right in self._raw():
            why = check_pair(left, right, self.size)
            if why is not None:
                both = isinstance(left, np.ndarray) and isinstance(right, np.ndarray) and left.size and right.size
                mism = (left is None) != (right is None) or bool(both and left.shape != right.shape)
                if mism:
                    self.stats.mismatched += 1
                else:
                    self.stats.dropped += 1
                self.stats.reasons.append(f"frame {index}: {why}")
                if self.on_corrupt == "raise":
                    raise VisionError(f"{self.name}: frame {index}: {why}")
                continue
            if self.size is None:
                self.size = (left.shape[1], left.shape[0])
            self.stats.delivered += 1
            yield StereoFrame(index, float(t), left, right)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class ArraySource(StereoSource):
    """Frames from memory: an iterable of ``(t, left, right)`` (tests, replays)."""

    name = "arrays"

    def __init__(self, pairs: Iterable, **kw):
        super().__init__(**kw)
        self._pairs = pairs

    def _raw(self):
        for i, (t, l, r) in enumerate(self._pairs):
            yield i, t, l, r


class SynthFolderSource(StereoSource):
    """A folder written by ``vishap synth`` (read through :mod:`vishap.sim.reader` when available)."""

    def __init__(self, folder: str | os.PathLike, **kw):
        super().__init__(**kw)
        from vishap.vision.evaluate import open_sequence  # vishap.sim.reader, or the layout reader

        self.folder = Path(folder)
        self.name = str(folder)
        self.sequence = open_sequence(folder)
        self.rig = self.sequence.rig

    def __len__(self) -> int:
        return len(self.sequence)

    def _raw(self):
        for i in range(len(self.sequence)):
            try:
                f = self.sequence[i]
            except Exception as exc:  # a broken image file: counted, not fatal
                self.stats.reasons.append(f"frame {i}: unreadable ({exc})")
                yield i, float("nan"), None, None
                continue
            yield f.index, f.t, f.left, f.right


def _open_video(path) -> cv2.VideoCapture:
    path = str(path)
    if not Path(path).is_file():
        raise VisionError(f"{path}: video file not found")
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        raise VisionError(f"{path}: cannot open video (unsupported codec or not a video)")
    return cap


def _video_t(cap: cv2.VideoCapture, index: int, fps: float | None) -> float:
    if fps:
        return index / fps
    ms = cap.get(cv2.CAP_PROP_POS_MSEC)
    f = cap.get(cv2.CAP_PROP_FPS)
    if ms > 0 or index == 0:
        return ms / 1000.0
    return index / f if f > 0 else float(index)


class VideoPairSource(StereoSource):
    """Two recorded videos, frame ``i`` of one paired with frame ``i`` of the other."""

    def __init__(self, left_path, right_path, *, fps: float | None = None, **kw):
        super().__init__(**kw)
        self.name = f"{left_path},{right_path}"
        self.caps = (_open_video(left_path), _open_video(right_path))
        self.fps = fps

    def _raw(self):
        cl, cr = self.caps
        i = 0
        while True:
            okl, left = cl.read()
            okr, right = cr.read()
            if not okl and not okr:
                return
            t = _video_t(cl if okl else cr, i, self.fps or cl.get(cv2.CAP_PROP_FPS) or None)
            if okl != okr:  # one video ended early: count what is left of the other as mismatched
                yield i, t, left if okl else None, right if okr else None
                i += 1
                continue
            yield i, t, left, right
            i += 1

    def close(self) -> None:
        for c in self.caps:
            c.release()


def _split(img):
    if img is None or not isinstance(img, np.ndarray) or img.ndim < 2 or img.shape[1] < 2:
        return img, img
    w = img.shape[1]
    if w % 2:
        return img[:, : w // 2], img[:, w // 2 + 1:]  # odd width: sizes differ → mismatched
    return img[:, : w // 2], img[:, w // 2:]


class SideBySideVideoSource(StereoSource):
    """One video whose frames hold the left image in the left half and the right in the right half."""

    def __init__(self, path, *, fps: float | None = None, **kw):
        super().__init__(**kw)
        self.name = str(path)
        self.cap = _open_video(path)
        self.fps = fps

    def _raw(self):
        i = 0
        while True:
            ok, img = self.cap.read()
            if not ok:
                return
            l, r = _split(img)
            yield i, _video_t(self.cap, i, self.fps or self.cap.get(cv2.CAP_PROP_FPS) or None), l, r
            i += 1

    def close(self) -> None:
        self.cap.release()


class CameraSource(StereoSource):
    """Live cameras: two devices (grabbed back to back, then retrieved) or one side-by-side device.

    Time stamps come from ``clock`` (default ``time.monotonic``) at the grab, the I/O boundary.
    ``max_frames`` ends the stream (None: until a device fails ``max_failures`` times in a row).
    """

    def __init__(self, left: int | str, right: int | str | None = None, *, clock=time.monotonic,
                 max_frames: int | None = None, max_failures: int = 10, **kw):
        super().__init__(**kw)
        self.name = f"cam:{left}" + ("" if right is None else f",{right}")
        self.caps = [cv2.VideoCapture(left)] + ([] if right is None else [cv2.VideoCapture(right)])
        for c, dev in zip(self.caps, (left, right)):
            if not c.isOpened():
                self.close()
                raise VisionError(f"camera {dev}: cannot open (no such device or busy)")
        self.clock, self.max_frames, self.max_failures = clock, max_frames, max_failures

    def _raw(self):
        i, fails = 0, 0
        while self.max_frames is None or i < self.max_frames:
            oks = [c.grab() for c in self.caps]
            t = self.clock()
            imgs = [c.retrieve()[1] if ok else None for c, ok in zip(self.caps, oks)]
            if not all(oks):
                fails += 1
                if fails >= self.max_failures:
                    raise VisionError(f"{self.name}: {fails} failed grabs in a row")
            else:
                fails = 0
            l, r = (imgs[0], imgs[1]) if len(imgs) == 2 else _split(imgs[0])
            yield i, t, l, r
            i += 1

    def close(self) -> None:
        for c in self.caps:
            c.release()


def open_source(spec, **kw) -> StereoSource:
    """A source from a spec string (see the module docstring)."""
    s = str(spec)
    if s.startswith("cam:") or s.startswith("sbs-cam:"):
        devs = [int(d) if d.strip().isdigit() else d.strip() for d in s.split(":", 1)[1].split(",")]
        if len(devs) > 2 or not devs:
            raise VisionError(f"{s}: expected cam:LEFT,RIGHT or cam:SIDE_BY_SIDE")
        return CameraSource(devs[0], devs[1] if len(devs) == 2 else None, **kw)
    if s.startswith("sbs:"):
        return SideBySideVideoSource(s[4:], **kw)
    if "," in s:
        a, b = s.split(",", 1)
        return VideoPairSource(a, b, **kw)
    p = Path(s)
    if p.is_dir():
        return SynthFolderSource(p, **kw)
    if p.suffix.lower() in _VIDEO_EXT:
        return SideBySideVideoSource(p, **kw)
    raise VisionError(f"{s}: not a folder, video, video pair (A,B) or camera (cam:N[,M])")
