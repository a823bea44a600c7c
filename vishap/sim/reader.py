"""Reading a sequence written by ``vishap synth`` (layout: :mod:`vishap.sim.writer`; arrays:
``datasets/synthetic/README.md``).

``SyntheticSequence(folder)`` has ``.rig`` (:class:`~vishap.vision.rig.StereoRig`), ``.T_robot_cam``
(4, 4; None for a folder without it, e.g. one written by another tool), ``.gt`` (dict of the ``gt.npz`` arrays), ``len()``, and ``[i]`` / iteration giving
:class:`SynthFrame` ``(index, t, left, right, labels_left, labels_right)`` with images as written
(BGR ``uint8``, labels ``uint8``), from either layout of :mod:`vishap.scale.store` (PNG files or
lossless video). Problems raise :class:`~vishap._core.errors.VisionError` naming the file.
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vishap._core.errors import ConfigError, VisionError
from vishap.scale.store import STREAMS, open_frames
from vishap.vision.rig import StereoRig

__all__ = ["SynthFrame", "SyntheticSequence"]


@dataclass
class SynthFrame:
    index: int
    t: float
    left: np.ndarray
    right: np.ndarray
    labels_left: np.ndarray
    labels_right: np.ndarray


class SyntheticSequence:
    """A synthetic sequence folder (see the module docstring)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise VisionError(f"{self.folder}: synthetic sequence folder not found")
        if not (self.folder / "rig.yaml").is_file():
            raise VisionError(f"{self.folder}: not a synthetic sequence (no rig.yaml)")
        try:
            self.rig = StereoRig.load(self.folder / "rig.yaml")
        except ConfigError as exc:
            raise VisionError(f"{self.folder}: bad rig.yaml ({exc})") from None
        gt_path = self.folder / "gt.npz"
        try:
            with np.load(gt_path, allow_pickle=False) as z:
                self.gt = {k: z[k] for k in z.files}
        except (OSError, ValueError, zipfile.BadZipFile) as exc:
            raise VisionError(f"{gt_path}: cannot read ground truth ({exc})") from None
        if "t" not in self.gt:
            raise VisionError(f"{gt_path}: missing array 't'")
        T = self.gt.get("T_robot_cam")  # absent in folders written by other tools (then None)
        self.T_robot_cam = None if T is None else np.asarray(T, dtype=np.float64)
        self.t = np.asarray(self.gt["t"], dtype=np.float64)
        self.frames = open_frames(self.folder)
        if len(self.frames) != len(self.t):
            where = "left/" if self.frames.store == "png" else "frames.json"
            raise VisionError(f"{self.folder}: {len(self.frames)} images in {where} but {len(self.t)} frames in gt.npz")

    @property
    def scene(self) -> str:
        return str(self.gt.get("scene", ""))

    def __len__(self) -> int:
        return len(self.t)

    def _read(self, stream: str, i: int) -> np.ndarray:
        img = self.frames.read(stream, i)
        if img is None:
            where = f"{stream}/{i:06d}.png" if self.frames.store == "png" else f"{stream}.mkv frame {i}"
            raise VisionError(f"{self.folder / where}: missing or unreadable image")
        return img

    def __getitem__(self, i: int) -> SynthFrame:
        n = len(self)
        if not isinstance(i, (int, np.integer)):
            raise TypeError(f"frame index must be an integer, got {type(i).__name__}")
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"frame {i} out of range (sequence has {n} frames)")
        left, right, labels_left, labels_right = (self._read(s, int(i)) for s in STREAMS)
        return SynthFrame(int(i), float(self.t[i]), left, right, labels_left, labels_right)

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]
