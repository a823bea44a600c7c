"""How the frames of a sequence are stored: one PNG per image (the default layout of
:mod:`vishap.sim.writer`) or, compactly, one lossless video per image stream (issue 18, item 4).

The four streams of a sequence are ``left``, ``right`` (colour, BGR) and ``labels/left``,
``labels/right`` (8-bit labels). Layouts::

    png:    left/000000.png …, right/…, labels/left/…, labels/right/…
    video:  left.mkv, right.mkv, labels/left.mkv, labels/right.mkv, frames.json

A video is FFV1 (a lossless intra-frame codec) in Matroska, written by the ffmpeg that
``imageio-ffmpeg`` ships (colour as ``bgr0``, labels as ``gray``: every pixel comes back as written)
with ffmpeg's bit-exact flags, so the same frames give the same bytes (no random segment id, no
date, no version string). ``frames.json`` says the layout, the frame count and the size.

Readers (:class:`PngFrames`, :class:`VideoFrames`, both from :func:`open_frames`) give
``read(stream, i)`` → the image as written; a video is decoded forwards (FFV1 frames are all key
frames, but seeking through OpenCV is not frame-exact on every container), reopened when asked for
an earlier frame. Only NumPy, OpenCV and imageio-ffmpeg are used: the vision package reads
recordings through this module without importing the simulator.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

from vishap._core.errors import ConfigError, VisionError

__all__ = ["STORES", "STREAMS", "INDEX", "stored_as", "open_frames", "PngFrames", "VideoFrames", "PngSink", "VideoSink",
           "make_sink", "frame_name"]

STORES = ("png", "video")
STREAMS = ("left", "right", "labels/left", "labels/right")
INDEX = "frames.json"
_FORMAT = "vishap-frames/ffv1-mkv"
_PNG = [cv2.IMWRITE_PNG_COMPRESSION, 1]  # noisy 640×480 frames: 25 ms vs 38 ms at level 3, +1 % size
# bit-exact container and codec (same frames, same bytes), no metadata, FFV1 version 3 with slice CRCs
_FFV1 = ["-fflags", "+bitexact", "-flags:v", "+bitexact", "-map_metadata", "-1", "-level", "3", "-slicecrc", "1",
         "-g", "1", "-threads", "1"]


def frame_name(i: int) -> str:
    return f"{int(i):06d}.png"


def _colour(stream: str) -> bool:
    return not stream.startswith("labels/")


def stored_as(folder: str | os.PathLike) -> str | None:
    """``"video"`` for a folder with ``frames.json``, ``"png"`` for one with ``left/``, else None."""
    folder = Path(folder)
    if (folder / INDEX).is_file():
        return "video"
    if (folder / "left").is_dir():
        return "png"
    return None


# -- writing ---------------------------------------------------------------------------------------
class PngSink:
    """One PNG per image, encoded on two threads (PNG encoding releases the GIL, so it overlaps
    the rendering of the next frame); at most two frames wait, and the first failure is raised."""

    def __init__(self, folder: Path, size: tuple[int, int], fps: float):
        from concurrent.futures import ThreadPoolExecutor

        self.dirs = {s: folder / s for s in STREAMS}
        for d in self.dirs.values():
            d.mkdir(parents=True)
        self.pool = ThreadPoolExecutor(max_workers=2)
        self.pending: list = []

    def write(self, i: int, images: dict[str, np.ndarray]) -> None:
        name = frame_name(i)
        for s in STREAMS:
            self.pending.append(self.pool.submit(_write_png, self.dirs[s] / name, images[s]))
        while len(self.pending) > 8:
            self.pending.pop(0).result()

    def close(self, ok: bool = True) -> None:
        try:
            while ok and self.pending:
                self.pending.pop(0).result()
        finally:
            for f in self.pending:
                f.cancel()
            self.pool.shutdown(wait=True)


def _write_png(path: Path, img: np.ndarray) -> None:
    if not cv2.imwrite(str(path), img, _PNG):
        raise OSError(f"cv2.imwrite failed for {path}")


class VideoSink:
    """One FFV1 video per stream, each encoded by its own ffmpeg process fed through a pipe (the
    encoding runs beside the rendering); ``frames.json`` is written when all are complete."""

    def __init__(self, folder: Path, size: tuple[int, int], fps: float):
        import imageio_ffmpeg

        self.folder, self.size, self.fps, self.n = folder, (int(size[0]), int(size[1])), float(fps), 0
        (folder / "labels").mkdir(parents=True, exist_ok=True)
        self.writers = {}
        for s in STREAMS:
            colour = _colour(s)
            w = imageio_ffmpeg.write_frames(
                str(folder / f"{s}.mkv"), self.size, pix_fmt_in="bgr24" if colour else "gray",
                pix_fmt_out="bgr0" if colour else "gray", fps=self.fps, quality=None, codec="ffv1",
                macro_block_size=1, ffmpeg_log_level="error", output_params=_FFV1)
            w.send(None)  # start ffmpeg
            self.writers[s] = w

    def write(self, i: int, images: dict[str, np.ndarray]) -> None:
        if i != self.n:
            raise ValueError(f"video frames are written in order: expected frame {self.n}, got {i}")
        for s in STREAMS:
            img = images[s]
            want = (self.size[1], self.size[0], 3) if _colour(s) else (self.size[1], self.size[0])
            if img.dtype != np.uint8 or img.shape != want:
                raise ValueError(f"{s}: expected uint8 {want}, got {img.dtype} {img.shape}")
            self.writers[s].send(np.ascontiguousarray(img))
        self.n += 1

    def close(self, ok: bool = True) -> None:
        errors = []
        for w in self.writers.values():
            try:
                w.close()  # waits for ffmpeg to finish the file; kills it on failure
            except Exception as exc:  # noqa: BLE001 - the first one is reported below
                errors.append(exc)
        if ok and errors:
            raise OSError(f"ffmpeg could not write the video ({errors[0]})")
        if ok:
            (self.folder / INDEX).write_text(json.dumps(
                {"format": _FORMAT, "frames": self.n, "size": list(self.size), "fps": self.fps,
                 "streams": {s: f"{s}.mkv" for s in STREAMS}}, sort_keys=True) + "\n")


def make_sink(store: str, folder: Path, size: tuple[int, int], fps: float):
    """The writer of ``store`` (``png`` or ``video``) into ``folder``."""
    if store == "png":
        return PngSink(folder, size, fps)
    if store == "video":
        return VideoSink(folder, size, fps)
    raise ConfigError(f"unknown store {store!r}; expected one of {list(STORES)}", field="store")


# -- reading ---------------------------------------------------------------------------------------
class PngFrames:
    """The PNG layout: frame ``i`` of a stream is the ``i``-th file of ``left/`` by name."""

    store = "png"

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        self.names = sorted(p.name for p in (self.folder / "left").glob("*.png"))

    def __len__(self) -> int:
        return len(self.names)

    def read(self, stream: str, i: int) -> np.ndarray | None:
        """The image, or None when its file is missing or unreadable."""
        return cv2.imread(str(self.folder / stream / self.names[i]),
                          cv2.IMREAD_COLOR if _colour(stream) else cv2.IMREAD_UNCHANGED)


class VideoFrames:
    """The video layout (see the module docstring)."""

    store = "video"

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        path = self.folder / INDEX
        try:
            index = json.loads(path.read_text())
            self.n = int(index["frames"])
            self.size = tuple(int(v) for v in index["size"])
            if index.get("format") != _FORMAT:
                raise ValueError(f"format {index.get('format')!r}, expected {_FORMAT!r}")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise VisionError(f"{path}: not a frame index of a video sequence ({exc})") from None
        self._caps: dict[str, list] = {}  # stream -> [VideoCapture, index of the next frame it gives]

    def __len__(self) -> int:
        return self.n

    def _open(self, stream: str) -> list:
        path = self.folder / f"{stream}.mkv"
        if not path.is_file():
            raise VisionError(f"{path}: missing video")
        cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        if not cap.isOpened():
            raise VisionError(f"{path}: cannot open the video (not FFV1/Matroska, or damaged)")
        if not _colour(stream):
            cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)  # labels come back as one 8-bit channel
        self._caps[stream] = [cap, 0]
        return self._caps[stream]

    def read(self, stream: str, i: int) -> np.ndarray | None:
        """The image (None past the frames the video holds: a truncated file)."""
        if not 0 <= i < self.n:
            raise IndexError(f"frame {i} out of range (sequence has {self.n} frames)")
        st = self._caps.get(stream)
        if st is None or st[1] > i:
            if st is not None:
                st[0].release()
            st = self._open(stream)
        cap = st[0]
        while st[1] < i:
            if not cap.grab():
                return None
            st[1] += 1
        ok, img = cap.read()
        if not ok:
            return None
        st[1] += 1
        if not _colour(stream) and img.ndim == 3:
            img = img[..., 0]
        return img

    def close(self) -> None:
        for cap, _ in self._caps.values():
            cap.release()
        self._caps.clear()


def open_frames(folder: str | os.PathLike):
    """The frames of a sequence folder in either layout."""
    return VideoFrames(folder) if stored_as(folder) == "video" else PngFrames(folder)
