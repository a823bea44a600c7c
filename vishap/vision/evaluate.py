"""Evaluation of the vision pipeline on labelled synthetic sequences (VisHap §2.1 / §3 figures).

Segmentation uses the paper's three ratios over all labelled pixels of both views (frames after the
background-learning frames): ``seg_correct`` (mask agrees with "label == skin"), ``seg_false_positive``
(mask says skin, label does not) and ``seg_false_negative``. Masks are produced before any label of
the evaluated sequence is read.

Tip accuracy is measured on frames where the ground truth says the tip is visible in both views:
``tip2d_rms_px`` (RMS over the four image coordinates — the per-coordinate RMS), ``tip3d_rms_mm``
(RMS of the 3-D distance to ``tip_cam``) and ``detection_rate``; frames where the tip is hidden are
reported separately (``hidden_frames``, ``false_detections`` on them). ``track_losses`` counts the
times the left tracker lost the finger while the tip stayed visible.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vishap._core.errors import VisionError
from vishap.scale.store import open_frames
from vishap.vision.pipeline import PipelineConfig, VisionPipeline
from vishap.vision.rig import StereoRig
from vishap.vision.skin_model import SkinModel

__all__ = ["SequenceReader", "open_sequence", "evaluate_sequence", "segmentation_ratios", "fit_skin_model"]


@dataclass
class _Frame:
    index: int
    t: float
    left: np.ndarray
    right: np.ndarray
    labels_left: np.ndarray | None = None
    labels_right: np.ndarray | None = None


class SequenceReader:
    """Reads the folder layout ``vishap synth`` writes (``rig.yaml``, ``left/``, ``right/``,
    ``labels/left|right/``, ``gt.npz``; or the images as lossless videos, :mod:`vishap.scale.store`).
    Vision reads recordings itself: it never imports the simulator (:mod:`vishap.sim` builds on
    vision, not the other way round)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        if not (self.folder / "rig.yaml").is_file():
            raise VisionError(f"{self.folder}: not a synthetic sequence (no rig.yaml)")
        self.rig = StereoRig.load(self.folder / "rig.yaml")
        self._frames = open_frames(self.folder)
        gt_path = self.folder / "gt.npz"
        self.gt = dict(np.load(gt_path, allow_pickle=False)) if gt_path.is_file() else {}
        self.T_robot_cam = self.gt.get("T_robot_cam")
        if "t" in self.gt and len(self.gt["t"]) != len(self._frames):
            raise VisionError(f"{self.folder}: {len(self._frames)} images in the sequence but {len(self.gt['t'])} frames in gt.npz")

    def __len__(self) -> int:
        return len(self._frames)

    def __getitem__(self, i: int) -> _Frame:
        def read(stream, colour=True):
            img = self._frames.read(stream, i)
            if img is None and colour:
                raise VisionError(f"{self.folder}: {stream} image of frame {i} missing or unreadable")
            return img

        t = float(self.gt["t"][i]) if "t" in self.gt else float(i)
        return _Frame(i, t, read("left"), read("right"), read("labels/left", False), read("labels/right", False))

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]


def open_sequence(folder):
    """A recorded sequence folder (the layout ``vishap synth`` writes)."""
    return SequenceReader(folder)


def segmentation_ratios(mask: np.ndarray, labels: np.ndarray, skin_label: int = 1) -> np.ndarray:
    """Counts ``[correct, false_positive, false_negative, total]`` of one mask against its labels."""
    pred = mask > 0
    gt = labels == skin_label
    fp = int(np.count_nonzero(pred & ~gt))
    fn = int(np.count_nonzero(gt & ~pred))
    n = gt.size
    return np.array([n - fp - fn, fp, fn, n], np.int64)


def fit_skin_model(folders, *, frames_per_sequence: int = 20, **kw) -> SkinModel:
    """Fit the Gaussian hue skin model from the labels of the given sequences (never evaluate on them)."""
    imgs, labs, names = [], [], []
    for folder in folders:
        seq = open_sequence(folder)
        n = len(seq)
        for i in np.linspace(0, n - 1, min(n, frames_per_sequence)).astype(int):
            f = seq[int(i)]
            for img, lab in ((f.left, f.labels_left), (f.right, f.labels_right)):
                if lab is not None and np.any(lab == 1):
                    imgs.append(img)
                    labs.append(lab)
        names.append(Path(folder).name)
    return SkinModel.fit(imgs, labs, source="labels of " + ", ".join(names), **kw)


def evaluate_sequence(folder, *, skin_model: SkinModel | None = None, config: PipelineConfig | None = None,
                      max_frames: int | None = None, seg_every: int = 1, keep_tracks: bool = False,
                      progress: bool = False) -> dict:
    """Run the pipeline over a labelled sequence and score it (see the module docstring); ``progress``:
    a bar on stderr (on a terminal)."""
    from vishap._core.results import progress as bar

    seq = open_sequence(folder)
    gt = seq.gt
    n = len(seq) if max_frames is None else min(len(seq), max_frames)
    cfg = config or PipelineConfig()
    if "hand_free_frames" in gt:  # learn the background on exactly the sequence's hand-free frames
        cfg = dataclasses.replace(cfg, learn_frames=int(gt["hand_free_frames"]))
    pipe = VisionPipeline(seq.rig, skin_model=skin_model, config=cfg)
    estimates, masks_counts = [], np.zeros(4, np.int64)
    frames_for_seg = []
    for i in bar(range(n), desc=f"eval {Path(folder).name}", unit="frame", quiet=not progress):
        f = seq[i]
        est = pipe.process(f)
        estimates.append(est)
        if est.mode != "learning" and (i % seg_every == 0):
            # full-frame masks for the segmentation ratios (not timed; labels read only afterwards)
            frames_for_seg.append((i, pipe.segmenters["left"].segment(f.left), pipe.segmenters["right"].segment(f.right)))
    for i, ml, mr in frames_for_seg:
        f = seq[i]
        masks_counts += segmentation_ratios(ml, f.labels_left) + segmentation_ratios(mr, f.labels_right)
    return score(estimates, gt, masks_counts, keep_tracks=keep_tracks, rig=seq.rig) | {"frames": n, "folder": str(folder)}


DEPTH_BINS_M = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 1.0)
GROSS_MM = 10.0  # a 3-D error above this is a wrong finger or a lost cap, not the noise of a fit


def error_by_depth(estimates, gt: dict, rig, frames) -> dict:
    """Where the 3-D error comes from, per depth bin (``DEPTH_BINS_M``, true depth): RMS of the
    rectified column and row errors of each view, of the disparity error (the difference of the two
    columns' errors), the 3-D error split into depth and lateral parts, and the 3-D RMS with and
    without gross errors (above ``GROSS_MM``). Image errors are of the reported (filtered) tips;
    the 3-D point may use a disparity filtered on its own (PipelineConfig.disparity_q), so the
    depth error is not always the disparity error times z²/(f·B)."""
    rows = []
    for i in frames:
        e = estimates[i]
        el = rig.rectify_points(np.vstack([e.uv_left, gt["tip_uv_left"][i]]), "left")
        er = rig.rectify_points(np.vstack([e.uv_right, gt["tip_uv_right"][i]]), "right")
        dl, dr = el[0] - el[1], er[0] - er[1]
        p, g = np.asarray(e.p_cam), np.asarray(gt["tip_cam"][i])
        rows.append((g[2], dl[0], dl[1], dr[0], dr[1], dl[0] - dr[0], p[2] - g[2], np.hypot(*(p[:2] - g[:2])),
                     np.linalg.norm(p - g)))
    a = np.array(rows).reshape(-1, 9)
    rms = lambda x: float(np.sqrt(np.mean(np.square(x)))) if len(x) else None
    out = {}
    for lo, hi in zip(DEPTH_BINS_M[:-1], DEPTH_BINS_M[1:]):
        sel = (a[:, 0] >= lo) & (a[:, 0] < hi)
        if not sel.any():
            continue
        b = a[sel]
        fine = b[b[:, 8] * 1e3 <= GROSS_MM]
        out[f"{lo:.1f}-{hi:.1f}"] = {
            "frames": int(sel.sum()), "gross": int(len(b) - len(fine)),
            "u_left_px": rms(fine[:, 1]), "v_left_px": rms(fine[:, 2]), "u_right_px": rms(fine[:, 3]),
            "v_right_px": rms(fine[:, 4]), "disparity_px": rms(fine[:, 5]),
            "depth_mm": None if not len(fine) else rms(fine[:, 6]) * 1e3,
            "lateral_mm": None if not len(fine) else rms(fine[:, 7]) * 1e3,
            "tip3d_rms_mm": rms(b[:, 8]) * 1e3,
            "tip3d_rms_mm_without_gross": None if not len(fine) else rms(fine[:, 8]) * 1e3}
    return out


def score(estimates, gt: dict, seg_counts: np.ndarray, *, keep_tracks: bool = False, rig=None) -> dict:
    n = len(estimates)
    vis_l = np.asarray(gt.get("tip_visible_left", np.ones(n, bool)))[:n].astype(bool)
    vis_r = np.asarray(gt.get("tip_visible_right", np.ones(n, bool)))[:n].astype(bool)
    learning = np.array([e.mode == "learning" for e in estimates])
    visible = vis_l & vis_r & ~learning
    found = np.array([e.found for e in estimates])
    e2, e3, z = [], [], []
    for i in np.flatnonzero(visible & found):
        e = estimates[i]
        e2.append(np.r_[e.uv_left - gt["tip_uv_left"][i], e.uv_right - gt["tip_uv_right"][i]])
        e3.append(np.linalg.norm(e.p_cam - gt["tip_cam"][i]))
        z.append(gt["tip_cam"][i][2])
    e2, e3, z = np.array(e2).reshape(-1, 4), np.array(e3), np.array(z)
    losses = 0
    tracking_prev = False
    for i, e in enumerate(estimates):
        if learning[i]:
            continue
        tracking = e.confidence > 0
        if tracking_prev and not tracking and visible[i]:
            losses += 1
        tracking_prev = tracking
    processed = [e for e in estimates if e.mode != "learning"]
    ms = np.array([e.timings.get("total_ms", np.nan) for e in processed])
    ms_tracked = np.array([e.timings.get("total_ms", np.nan) for e in processed if e.mode == "tracked"])
    ms_full = np.array([e.timings.get("total_ms", np.nan) for e in processed if e.mode == "full"])
    c, fp, fn, tot = (int(v) for v in seg_counts)
    hidden = int(np.count_nonzero(~visible & ~learning))
    out = {
        "seg_correct": c / tot if tot else None,
        "seg_false_positive": fp / tot if tot else None,
        "seg_false_negative": fn / tot if tot else None,
        "tip2d_rms_px": float(np.sqrt(np.mean(e2 ** 2))) if len(e2) else None,
        "tip2d_p95_px": float(np.percentile(np.abs(e2), 95)) if len(e2) else None,
        "tip3d_rms_mm": float(np.sqrt(np.mean(e3 ** 2)) * 1e3) if len(e3) else None,
        "tip3d_median_mm": float(np.median(e3) * 1e3) if len(e3) else None,
        "tip3d_rms_mm_without_gross": (float(np.sqrt(np.mean(np.square(e3[e3 * 1e3 <= GROSS_MM]))) * 1e3)
                                       if np.any(e3 * 1e3 <= GROSS_MM) else None),
        "gross_errors": int(np.count_nonzero(e3 * 1e3 > GROSS_MM)),
        "depth_range_m": [float(z.min()), float(z.max())] if len(z) else None,
        "detection_rate": (float(np.count_nonzero(visible & found) / np.count_nonzero(visible))
                           if np.any(visible) else None),  # no frame shows the tip: undefined, not 0
        "visible_frames": int(np.count_nonzero(visible)),
        "hidden_frames": hidden,
        "false_detections": int(np.count_nonzero(~visible & ~learning & found)),
        "track_losses": losses,
        "ms_per_pair": float(np.nanmedian(ms)) if len(ms) else None,
        "ms_per_pair_tracked": float(np.nanmedian(ms_tracked)) if len(ms_tracked) else None,
        "ms_per_pair_full": float(np.nanmedian(ms_full)) if len(ms_full) else None,
        "frames_tracked": int(len(ms_tracked)),
        "frames_full": int(len(ms_full)),
    }
    if "phase" in gt and "phase_names" in gt:
        out["by_phase"] = _by_phase(estimates, gt, visible, found)
    if rig is not None and len(e3):
        out["by_depth"] = error_by_depth(estimates, gt, rig, np.flatnonzero(visible & found))
    if keep_tracks:
        out["tracks"] = [track_record(e) for e in estimates]
    return out


def _by_phase(estimates, gt, visible, found) -> dict:
    """Detection rate and tip errors per trajectory phase (approach, press, slide, occlusion …)."""
    n = len(estimates)
    phase = np.asarray(gt["phase"])[:n]
    names = [str(x) for x in np.asarray(gt["phase_names"])]
    res = {}
    for k in np.unique(phase):
        sel = phase == k
        vis = sel & visible
        hit = vis & found
        e2 = [np.r_[estimates[i].uv_left - gt["tip_uv_left"][i], estimates[i].uv_right - gt["tip_uv_right"][i]]
              for i in np.flatnonzero(hit)]
        e3 = [np.linalg.norm(estimates[i].p_cam - gt["tip_cam"][i]) for i in np.flatnonzero(hit)]
        name = names[int(k)] if 0 <= int(k) < len(names) else str(int(k))
        res[name] = {"frames": int(sel.sum()), "visible": int(vis.sum()),
                     "detection_rate": float(hit.sum() / vis.sum()) if vis.sum() else None,
                     "tip2d_rms_px": float(np.sqrt(np.mean(np.square(e2)))) if e2 else None,
                     "tip3d_rms_mm": float(np.sqrt(np.mean(np.square(e3))) * 1e3) if e3 else None,
                     "false_detections": int((sel & ~visible & found).sum())}
    return res


def track_record(e) -> dict:
    """One JSON-ready row of ``vishap track`` output."""
    lst = lambda a: None if a is None else [float(v) for v in np.asarray(a).ravel()]
    return {"t": e.t, "found": bool(e.found), "mode": e.mode, "tip_uv_left": lst(e.uv_left),
            "tip_uv_right": lst(e.uv_right), "tip_cam": lst(e.p_cam),
            "cov_cam": None if e.cov_cam is None else np.asarray(e.cov_cam).tolist(),
            "confidence": float(e.confidence), "timing_ms": {k: round(v, 4) for k, v in e.timings.items()},
            "reason": e.reason}
