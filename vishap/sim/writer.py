"""Writing a synthetic sequence in the folder layout of issue 3 (item 4)::

    OUT/rig.yaml                      StereoRig.save (OpenCV FileStorage)
    OUT/left/000000.png …             colour, BGR, 8-bit
    OUT/right/000000.png …
    OUT/labels/left/000000.png …      8-bit labels: 0 background, 1 skin/hand, 2 device + passive object, 3 scene object
    OUT/labels/right/000000.png …
    OUT/gt.npz                        ground truth (datasets/synthetic/README.md documents every array)

or, with ``SequenceSpec(store="video")``, the four image streams as lossless FFV1 videos
(``left.mkv``, ``right.mkv``, ``labels/left.mkv``, ``labels/right.mkv`` and ``frames.json``;
:mod:`vishap.scale.store`), read back pixel for pixel by the same readers.

Everything is checked before the first pixel is rendered; the sequence is written into a hidden
temporary folder beside ``OUT`` and renamed into place at the end (:mod:`vishap._core.output`), so a
failure (bad input, a full disk, Ctrl-C, SIGTERM) leaves no half-written folder and removes nothing
it did not create. The bytes depend only on the inputs: PNGs are
written with fixed settings and ``gt.npz`` is a zip whose entries carry a fixed date.
"""
from __future__ import annotations

import io
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from vishap._core.errors import ConfigError
from vishap._core.output import output_dir
from vishap.scale.store import frame_name, make_sink
from vishap.sim.sequence import SequenceSpec, constants, make_renderer, prepare, render_frames

__all__ = ["write_sequence", "save_npz_deterministic", "frame_name"]

_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def save_npz_deterministic(path: str | Path, arrays: dict) -> Path:
    """Like ``numpy.savez_compressed`` but byte-identical for identical arrays (fixed zip dates, sorted)."""
    path = Path(path)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(arrays[name]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())
    return path


def write_sequence(out: str | Path, spec: SequenceSpec, *, overwrite: bool = False, progress: bool = False,
                   on_frame: Callable[[int], None] | None = None) -> Path:
    """Render ``spec`` and write it to the folder ``out`` (see the module docstring); returns ``out``.
    ``on_frame(n)`` is called after each frame with the number of frames handed to the writer.

    ``out`` must not exist or be empty, unless ``overwrite``. Raises :class:`ConfigError` with one
    clear message for bad input; nothing is left on disk in that case, and nothing this call did
    not create is removed (:func:`vishap._core.output.output_dir`).
    """
    p = prepare(spec)  # unknown scene / trajectory, bad frames, lighting, … fail here
    with output_dir(out, overwrite=overwrite) as folder:
        try:
            _write_into(folder.path, p, progress, on_frame)
        except OSError as exc:
            raise ConfigError(f"cannot write the sequence ({exc.strerror or exc})", file=folder.final) from None
    return folder.final


def _write_into(folder: Path, p, progress: bool, on_frame) -> None:
    from tqdm import tqdm

    p.rig.save(folder / "rig.yaml")
    rows = []
    renderer = make_renderer(p)
    sink = make_sink(p.spec.store, folder, p.rig.image_size, p.trajectory.spec.fps)
    ok = False
    try:
        frames = render_frames(p, renderer)
        bar = tqdm(frames, total=len(p.times), desc=f"synth {p.scene_spec.name}", unit="frame", disable=not progress)
        for _, pair, row in bar:
            sink.write(int(row["index"]), {"left": pair.left, "right": pair.right, "labels/left": pair.labels_left,
                                           "labels/right": pair.labels_right})
            rows.append(row)
            if on_frame is not None:
                on_frame(len(rows))
        consts = constants(p, renderer)
        ok = True
    finally:
        try:
            sink.close(ok)
        finally:
            renderer.close()
    gt = {k: np.stack([np.asarray(r[k]) for r in rows]) for k in rows[0]}
    gt["index"] = gt["index"].astype(np.int64)
    gt["phase"] = gt["phase"].astype(np.int64)
    for k in ("tip_visible_left", "tip_visible_right", "in_contact", "hand_visible", "occluder_present"):
        gt[k] = gt[k].astype(bool)
    gt.update(consts)
    save_npz_deterministic(folder / "gt.npz", gt)
