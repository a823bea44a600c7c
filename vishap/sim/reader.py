"""Reading a sequence written by ``vishap synth`` (layout: :mod:`vishap.sim.writer`; arrays:
``datasets/synthetic/README.md``).

``SyntheticSequence(folder)`` has ``.rig`` (:class:`~vishap.vision.rig.StereoRig`), ``.T_robot_cam``
(4, 4; None for a folder without it, e.g. one written by another tool), ``.gt`` (dict of the ``gt.npz`` arrays), ``len()``, and ``[i]`` / iteration giving
:class:`SynthFrame` ``(index, t, left, right, labels_left, labels_right)`` with images as written
(BGR ``uint8``, labels ``uint8``). Problems raise :class:`~vishap._core.errors.VisionError` naming the file.
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vishap._core.errors import ConfigError, VisionError
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
        n_png = len(list((self.folder / "left").glob("*.png")))
        if n_png != len(self.t):
            raise VisionError(f"{self.folder}: {n_png} images in left/ but {len(self.t)} frames in gt.npz")

    @property
    def scene(self) -> str:
        return str(self.gt.get("scene", ""))

    def __len__(self) -> int:
        return len(self.t)

    def _read(self, path: Path, flag: int) -> np.ndarray:
        img = cv2.imread(str(path), flag)
        if img is None:
            raise VisionError(f"{path}: missing or unreadable image")
        return img

    def __getitem__(self, i: int) -> SynthFrame:
        n = len(self)
        if not isinstance(i, (int, np.integer)):
            raise TypeError(f"frame index must be an integer, got {type(i).__name__}")
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"frame {i} out of range (sequence has {n} frames)")
        name = f"{int(i):06d}.png"
        f = self.folder
        return SynthFrame(int(i), float(self.t[i]), self._read(f / "left" / name, cv2.IMREAD_COLOR),
                          self._read(f / "right" / name, cv2.IMREAD_COLOR),
                          self._read(f / "labels" / "left" / name, cv2.IMREAD_UNCHANGED),
                          self._read(f / "labels" / "right" / name, cv2.IMREAD_UNCHANGED))

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]
