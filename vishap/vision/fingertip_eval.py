"""2-D fingertip scores of any mono detector on real photos or video (``vishap eval fingertip``).

A *labels* CSV has the columns ``frame,u,v`` (other columns are ignored): ``frame`` is a file name
in an image folder, or the 0-based frame index in a video (or in a ``vishap synth`` folder, whose
left view is scored; a file name of its ``left/`` folder works too); ``u,v`` is the annotated end of
the index fingertip in pixels, empty when it is not visible.

Scores, on the annotated frames where the tip is visible:

``detection_rate``  share with a detection;
``pck_10/20/30``    share with a detected ``tip_end_uv`` within 10/20/30 px of the annotation (a miss
                    is a failure);
``median_error_px`` median distance over the frames with a detection;
``ms_per_frame``    median wall time of ``detector.process`` per frame.
Frames annotated as hidden give ``hidden_frames`` and ``false_detections`` (a detection there).

Photos in a folder are independent shots: the detector is reset before each (no tracking, no
background across unrelated photos) unless ``sequence=True``. Video frames are a sequence: every
frame is processed in order (tracking and background learning see them all); only annotated
frames are scored.
"""
from __future__ import annotations

import csv
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vishap._core.config import write_atomic
from vishap._core.errors import ConfigError, VisionError
from vishap.vision.detector import MonoDetection, MonoDetector

__all__ = ["FingertipLabel", "read_fingertip_labels", "MonoFrames", "open_mono_frames", "score_fingertips",
           "evaluate_fingertip", "write_fingertip_results", "PCK_RADII_PX"]

PCK_RADII_PX = (10, 20, 30)
_IMAGE_EXT = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp"}
_VIDEO_EXT = {".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mjpg"}


@dataclass(frozen=True)
class FingertipLabel:
    frame: str                 # as written in the CSV
    row: int                   # CSV line number (header = 1)
    uv: np.ndarray | None      # annotated tip end, None when not visible


def read_fingertip_labels(path: str | os.PathLike) -> list[FingertipLabel]:
    """Read a labels CSV; a missing file, missing columns or a bad value raise one ConfigError naming
    the file and the row."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("labels file not found", file=path)
    try:
        with path.open(newline="") as f:
            reader = csv.DictReader(f)
            cols = [c.strip() for c in (reader.fieldnames or [])]
            missing = [c for c in ("frame", "u", "v") if c not in cols]
            if missing:
                raise ConfigError(f"missing column(s) {', '.join(missing)} (found: {', '.join(cols) or 'none'}); "
                                  "expected frame,u,v", file=path)
            reader.fieldnames = cols
            out, seen = [], {}
            for rec in reader:
                row = reader.line_num
                frame = (rec.get("frame") or "").strip()
                if not frame:
                    raise ConfigError(f"row {row}: empty 'frame'", file=path)
                if frame in seen:
                    raise ConfigError(f"row {row}: frame {frame!r} already labelled in row {seen[frame]}", file=path)
                seen[frame] = row
                u, v = (rec.get("u") or "").strip(), (rec.get("v") or "").strip()
                if not u and not v:
                    out.append(FingertipLabel(frame, row, None))
                    continue
                try:
                    uv = np.array([float(u), float(v)])
                except ValueError:
                    raise ConfigError(f"row {row}: u,v must be numbers or both empty, got {u!r},{v!r}",
                                      file=path) from None
                if not np.all(np.isfinite(uv)):
                    raise ConfigError(f"row {row}: u,v must be finite, got {u!r},{v!r}", file=path)
                out.append(FingertipLabel(frame, row, uv))
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text CSV ({exc.reason})", file=path) from None
    except csv.Error as exc:
        raise ConfigError(f"malformed CSV ({exc})", file=path) from None
    if not out:
        raise ConfigError("no labelled rows", file=path)
    return out


class MonoFrames:
    """The frames of a source in processing order: ``(key, t, image_or_reader)``.

    ``keys`` are what the labels' ``frame`` column refers to; ``sequence`` says whether the frames
    are consecutive video frames (True) or independent photos (False).
    """

    def __init__(self, spec: str, kind: str, items: list | None = None, video: str | None = None):
        self.spec, self.kind, self._items, self._video = spec, kind, items, video
        self.sequence = kind != "images"

    def keys(self) -> set[str] | None:
        """Known frame keys before reading (None for a video: known only after reading it)."""
        if self._items is None:
            return None
        return {k for item in self._items for k in item[0]}

    def __iter__(self) -> Iterator[tuple[tuple[str, ...], float, np.ndarray]]:
        if self._video is not None:
            cap = cv2.VideoCapture(self._video)
            if not cap.isOpened():
                raise VisionError(f"{self._video}: cannot open video (unsupported codec or not a video)")
            fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
            i = 0
            try:
                while True:
                    ok, img = cap.read()
                    if not ok:
                        return
                    yield (str(i),), i / fps, img
                    i += 1
            finally:
                cap.release()
        for keys, t, path in self._items:
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if img is None:
                raise VisionError(f"{path}: cannot read image (frame {keys[0]!r})")
            yield keys, t, img


def open_mono_frames(spec: str | os.PathLike) -> MonoFrames:
    """Frames of a folder of images, a video file, ``LEFT,RIGHT`` videos (left) or a ``vishap synth``
    folder (left view)."""
    s = str(spec)
    if "," in s and not Path(s).exists():
        left = s.split(",", 1)[0]
        return open_mono_frames(left) if Path(left).suffix.lower() in _VIDEO_EXT else _bad_source(s)
    p = Path(s)
    if p.is_dir():
        if (p / "rig.yaml").is_file() and (p / "left.mkv").is_file():  # stored as video (vishap.scale.store)
            return MonoFrames(s, "synth", video=str(p / "left.mkv"))
        if (p / "rig.yaml").is_file() and (p / "left").is_dir():
            files = sorted(f for f in (p / "left").iterdir() if f.suffix.lower() in _IMAGE_EXT)
            ts = _synth_times(p, len(files))
            return MonoFrames(s, "synth", [((str(i), f.name), ts[i], f) for i, f in enumerate(files)])
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in _IMAGE_EXT)
        if not files:
            raise VisionError(f"{p}: no images (.jpg, .png, …) in the folder")
        return MonoFrames(s, "images", [((f.name,), float(i), f) for i, f in enumerate(files)])
    if p.suffix.lower() in _VIDEO_EXT:
        if not p.is_file():
            raise VisionError(f"{p}: video file not found")
        return MonoFrames(s, "video", video=str(p))
    return _bad_source(s)


def _bad_source(s: str):
    raise VisionError(f"{s}: not an image folder, a video file, LEFT,RIGHT videos or a 'vishap synth' folder")


def _synth_times(folder: Path, n: int) -> np.ndarray:
    gt = folder / "gt.npz"
    if gt.is_file():
        with np.load(gt, allow_pickle=False) as d:
            if "t" in d.files and len(d["t"]) >= n:
                return np.asarray(d["t"][:n], dtype=np.float64)
    return np.arange(n) / 30.0


def score_fingertips(errors: list[float | None], hidden_found: list[bool] | None = None) -> dict:
    """Scores from per-frame errors (px; None = no detection) of frames with a visible tip."""
    n = len(errors)
    err = np.array([e for e in errors if e is not None], dtype=np.float64)
    rec = {"frames": n, "detection_rate": err.size / n if n else None}
    for r in PCK_RADII_PX:
        rec[f"pck_{r}"] = float(np.sum(err <= r)) / n if n else None
    rec["median_error_px"] = float(np.median(err)) if err.size else None
    if hidden_found is not None:
        rec["hidden_frames"] = len(hidden_found)
        rec["false_detections"] = int(sum(hidden_found))
    return rec


def evaluate_fingertip(source: str | os.PathLike, labels: str | os.PathLike, detector: MonoDetector, *,
                       sequence: bool | None = None, subset=None, progress: bool = False) -> tuple[dict, list[dict]]:
    """Run ``detector`` on ``source`` and score it against ``labels``: ``(record, per_frame_rows)``.

    ``subset``: optional set of frame keys; other labelled frames are ignored (still images are
    then only read when labelled and in the subset). Every labelled frame must exist in the source.
    """
    frames = open_mono_frames(source)
    lab = read_fingertip_labels(labels)
    if subset is not None:
        subset = {str(k) for k in subset}
        lab = [x for x in lab if x.frame in subset]
    by_key = {x.frame: x for x in lab}
    known = frames.keys()
    if known is not None:
        _check_exist(lab, known, labels, source)
    seq = frames.sequence if sequence is None else sequence
    from vishap._core.results import progress as bar

    rows, seen = [], set()
    detector.reset()
    total = len(by_key) if not seq else (None if frames._items is None else len(frames._items))
    for keys, t, img in bar(_frames_needed(frames, by_key, seq), total=total, desc="eval fingertip", unit="frame",
                            quiet=not progress):
        label = next((by_key[k] for k in keys if k in by_key), None)
        if not seq:
            detector.reset()
        t0 = time.perf_counter()
        det = detector.process(img, t)
        ms = (time.perf_counter() - t0) * 1e3
        if label is None:
            continue
        seen.add(label.frame)
        rows.append(_row(label, det, ms))
    if known is None:
        _check_exist([x for x in lab if x.frame not in seen], set(), labels, source)
    rows.sort(key=lambda r: r["row"])
    vis = [r for r in rows if r["u_gt"] is not None]
    hid = [r for r in rows if r["u_gt"] is None]
    rec = score_fingertips([r["error_px"] if r["found"] else None for r in vis], [r["found"] for r in hid])
    rec["ms_per_frame"] = float(np.median([r["ms"] for r in rows])) if rows else None
    rec["detector"] = getattr(detector, "name", type(detector).__name__)
    rec["source"] = str(source)
    rec["labels"] = str(labels)
    return rec, rows


def _frames_needed(frames: MonoFrames, by_key: dict, seq: bool):
    if seq or frames._items is None:
        yield from frames
        return
    # independent photos: read only the labelled ones
    items = frames._items
    frames._items = [it for it in items if any(k in by_key for k in it[0])]
    try:
        yield from frames
    finally:
        frames._items = items


def _check_exist(lab, known: set, labels, source) -> None:
    for x in lab:
        if x.frame not in known:
            raise ConfigError(f"row {x.row}: frame {x.frame!r} does not exist in {source}", file=labels)


def _row(label: FingertipLabel, det: MonoDetection, ms: float) -> dict:
    uv = det.tip_end_uv if det.found else None
    if uv is not None and not np.all(np.isfinite(uv)):
        uv = None
    err = None if uv is None or label.uv is None else float(np.hypot(*(np.asarray(uv, float) - label.uv)))
    cap = det.cap_uv if det.found and det.cap_uv is not None else None
    return {
        "frame": label.frame, "row": label.row,
        "u_gt": None if label.uv is None else float(label.uv[0]),
        "v_gt": None if label.uv is None else float(label.uv[1]),
        "found": uv is not None,
        "u": None if uv is None else float(uv[0]), "v": None if uv is None else float(uv[1]),
        "cap_u": None if cap is None else float(cap[0]), "cap_v": None if cap is None else float(cap[1]),
        "error_px": err, "ms": ms, "mode": det.mode, "confidence": float(det.confidence), "reason": det.reason,
    }


_COLUMNS = ("frame", "row", "u_gt", "v_gt", "found", "u", "v", "cap_u", "cap_v", "error_px", "ms", "mode",
            "confidence", "reason")


def write_fingertip_results(out: str | os.PathLike, record: dict, rows: list[dict], source, *,
                            worst: int = 12) -> list[Path]:
    """``OUT/fingertip.json``, ``OUT/frames.csv`` and overlays of the worst frames
    (``OUT/worst/NN_FRAME.png``: misses first, then the largest errors). Existing files of another run
    are never replaced: an ``OUT`` that already holds results is an error."""
    out = Path(out)
    if (out / "fingertip.json").exists() or (out / "frames.csv").exists() or (out / "worst").exists():
        raise ConfigError("already holds results of another run; choose a new folder", file=out)
    import io
    import json

    written = []
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: "" if r[k] is None else (f"{r[k]:.3f}" if isinstance(r[k], float) else r[k]) for k in _COLUMNS})
    written.append(write_atomic(out / "frames.csv", buf.getvalue()))
    bad = sorted((r for r in rows if r["u_gt"] is not None),
                 key=lambda r: (r["found"], -(r["error_px"] if r["error_px"] is not None else math.inf)))[:worst]
    want = {r["frame"]: r for r in bad}
    if want:
        for keys, _, img in open_mono_frames(source):
            hit = next((want[k] for k in keys if k in want), None)
            if hit is None:
                continue
            k = bad.index(hit)
            ok, png = cv2.imencode(".png", _overlay(img, hit))
            name = "".join(c if c.isalnum() or c in "-_." else "_" for c in hit["frame"])
            written.append(write_atomic(out / "worst" / f"{k:02d}_{Path(name).stem}.png", png.tobytes()))
            del want[hit["frame"]]
            if not want:
                break
    written.append(write_atomic(out / "fingertip.json", json.dumps(record, indent=1) + "\n"))
    return written


def _overlay(img: np.ndarray, r: dict) -> np.ndarray:
    out = img.copy()
    gt = (int(round(r["u_gt"])), int(round(r["v_gt"])))
    cv2.circle(out, gt, 30, (0, 200, 0), 1, cv2.LINE_AA)
    cv2.drawMarker(out, gt, (0, 255, 0), cv2.MARKER_CROSS, 14, 2)
    if r["found"]:
        p = (int(round(r["u"])), int(round(r["v"])))
        cv2.drawMarker(out, p, (0, 0, 255), cv2.MARKER_TILTED_CROSS, 14, 2)
        if r["cap_u"] is not None:
            cv2.circle(out, (int(round(r["cap_u"])), int(round(r["cap_v"]))), 3, (255, 0, 255), -1)
        text = f"{r['frame']}: {r['error_px']:.1f} px ({r['mode']})"
    else:
        text = f"{r['frame']}: missed ({r['reason'] or 'no detection'})"
    cv2.putText(out, text[:80], (5, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text[:80], (5, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return out
