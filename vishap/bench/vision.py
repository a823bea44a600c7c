"""``vishap bench vision``: speed against accuracy of the VisHap §2.1 pipeline and the peers a user
would pick instead, on the same labelled frames.

* pipeline: tracked-window mode and full-frame mode (ms per stereo pair, tip 2-D/3-D RMS);
* segmentation: parameter variants (bins, tile size, median size, hue×saturation bins), the
  torch/kornia batch backend (checked mask-for-mask against NumPy/OpenCV), and OpenCV's MOG2, KNN,
  CNT and GSOC background subtractors with the same skin model and median filter;
* stereo: sparse rectified triangulation against dense StereoBM / StereoSGBM sampled at the tip;
* 3-D tip: the masks' cap fits, the side-edge axis, the disparity filter, and refinements on the
  images (sub-pixel edges per view or jointly, ZNCC along the rectified row), with the error decomposed by depth
  (``vision_stereo_refinement.png``);
* Kalman: this filter against ``cv2.KalmanFilter`` and filterpy on the same measurements;
* speed: CPU time per stereo pair of the pipeline by mode (full-frame search, tracked window,
  recheck), against the goals of ≤ 4 ms per full-frame and ≤ 1 ms per tracked pair at 640×480.

Data: ``--data DIR...`` (folders written by ``vishap synth``); default a 70-frame wall sequence
rendered on the fly (seed 101), or the analytic toy scene where the renderer is unavailable.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from vishap.bench._common import machine_info, median_us, new_figure, save_figure, time_calls

HELP = "vision pipeline: segmentation, detection, stereo and Kalman against OpenCV/torch/filterpy peers"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", nargs="*", default=None,
                   help="synthetic sequence folders (default: a 70-frame 'vishap synth' wall sequence, seed 101)")
    p.add_argument("--frames", type=int, default=60, help="frames per sequence (default 60)")
    p.add_argument("--skin", default=None, help="skin model YAML (default: the shipped model)")
    p.add_argument("--quick", action="store_true", help="fewer variants and peers (for a smoke run)")
    p.add_argument("--stages", default=",".join(STAGES),
                   help=f"comma-separated stages to run (default all: {','.join(STAGES)})")
    p.add_argument("--variants", nargs="*", default=None,
                   help="refinement variants to run: those whose name contains one of these words (default all)")
    p.add_argument("--rounds", type=int, default=None, help="passes of the speed stage (default 3; --quick 1)")


STAGES = ("pipeline", "refinement", "segmentation", "stereo", "kalman", "speed", "constants")


def _default_data(tmp: Path) -> list[Path]:
    """A synthetic sequence long enough for the background frames plus a track: rendered by
    ``vishap synth`` when :mod:`vishap.sim` is importable, else the analytic toy scene."""
    try:
        from vishap.cli import main as cli

        if cli(["synth", "--scene", "wall", "--frames", "70", "--seed", "101", "--lighting", "ramp",
                "--out", str(tmp / "wall_101"), "--quiet"]) == 0:
            return [tmp / "wall_101"]
    except Exception:  # no renderer here (EGL missing): fall back to the toy scene
        pass
    from vishap.vision.toy import write_sequence

    write_sequence(tmp / "toy", seed=3, frames=40, learn=10, size=(640, 480))
    return [tmp / "toy"]


def _load(folder, n):
    from vishap.vision.evaluate import open_sequence

    seq = open_sequence(folder)
    return seq, [seq[i] for i in range(min(n, len(seq)))]


def _ratios(masks, frames):
    from vishap.vision.evaluate import segmentation_ratios

    c = np.zeros(4, np.int64)
    for m, f in zip(masks, frames):
        c += segmentation_ratios(m, f.labels_left)
    return {"seg_correct": c[0] / c[3], "seg_false_positive": c[1] / c[3], "seg_false_negative": c[2] / c[3]}


def _bench_segmentation(frames, learn, skin, quick):
    from vishap.vision.segment import SegmentConfig, Segmenter
    from vishap.vision.segment_torch import TorchSegmenter

    bg, live = frames[:learn], frames[learn:]
    variants = {"paper (5 px tiles, 8 bins, median 5)": SegmentConfig()}
    if not quick:
        variants |= {
            "bins 4": SegmentConfig(bins=4), "bins 16": SegmentConfig(bins=16),
            "tile 3": SegmentConfig(tile=3), "tile 8": SegmentConfig(tile=8),
            "median 1": SegmentConfig(median=1), "median 3": SegmentConfig(median=3), "median 7": SegmentConfig(median=7),
            "no tile dilation": SegmentConfig(dilate_tiles=0), "hue×sat 8×4": SegmentConfig(sat_bins=4),
        }
    out = {}
    for name, cfg in variants.items():
        seg = Segmenter(skin, cfg)
        seg.learn([f.left for f in bg])
        masks = [seg.segment(f.left) for f in live]
        k = iter(range(10 ** 9))
        dt = time_calls(lambda: seg.segment(live[next(k) % len(live)].left), 3 * len(live))
        dense = time_calls(lambda: seg.segment(live[next(k) % len(live)].left, method="dense"), len(live))
        out[name] = {"kind": "variant", "ms_per_image": median_us(dt) / 1e3, "ms_per_image_dense_tiles": median_us(dense) / 1e3,
                     **_ratios(masks, live)}
        if name.startswith("paper"):
            ref_masks, ref_seg = masks, seg
    # torch/kornia batch backend: same masks, time per image in a batch (HSV conversion included)
    tseg = TorchSegmenter(skin, ref_seg.config, ref_seg.background)
    hsv = lambda: np.stack([cv2.cvtColor(f.left, cv2.COLOR_BGR2HSV) for f in live])
    tmasks = tseg.segment(hsv())
    dt = time_calls(lambda: tseg.segment(hsv()), 3, warmup=1)
    out["torch/kornia batch"] = {"kind": "backend", "ms_per_image": median_us(dt) / 1e3 / len(live),
                                 "same_masks_as_numpy": bool(np.array_equal(tmasks, np.stack(ref_masks))),
                                 **_ratios(list(tmasks), live)}
    # OpenCV background subtractors + the same skin model and median
    peers = {"MOG2": cv2.createBackgroundSubtractorMOG2, "KNN": cv2.createBackgroundSubtractorKNN,
             "CNT": cv2.bgsegm.createBackgroundSubtractorCNT}
    if not quick:
        peers["GSOC"] = cv2.bgsegm.createBackgroundSubtractorGSOC
    med = ref_seg.config.median
    for name, make in peers.items():
        sub = make()
        for f in bg:
            sub.apply(f.left)
        masks, times = [], []
        for f in live:
            t0 = time.perf_counter()
            fg = sub.apply(f.left)
            m = cv2.bitwise_and(skin.mask(f.left), skin.mask(f.left), mask=(fg == 255).view(np.uint8))
            m = cv2.medianBlur(m, med) if med > 1 else m
            times.append(time.perf_counter() - t0)
            masks.append(m)
        out[f"{name} + skin + median"] = {"kind": "peer", "ms_per_image": float(np.median(times) * 1e3), **_ratios(masks, live)}
    return out


def _bench_pipeline(folder, n, skin):
    from vishap.vision.evaluate import evaluate_sequence
    from vishap.vision.pipeline import PipelineConfig

    out = {}
    for name, cfg in (("tracked window", PipelineConfig()), ("full frame", PipelineConfig(tracking=False)),
                      ("tracked, no periodic recheck", PipelineConfig(recheck_frames=0))):
        r = evaluate_sequence(folder, skin_model=skin, config=cfg, max_frames=n, seg_every=10 ** 9)
        out[name] = {k: r[k] for k in ("ms_per_pair", "ms_per_pair_tracked", "ms_per_pair_full", "tip2d_rms_px",
                                       "tip3d_rms_mm", "tip3d_median_mm", "detection_rate", "false_detections",
                                       "track_losses", "visible_frames")}
    return out


SPEED_GOALS_MS = {"full frame": 4.0, "tracked": 1.0}  # issue 14 item 9, per 640×480 stereo pair


def _bench_speed(seq, frames, skin, learn: int, rounds: int) -> dict:
    """CPU time per stereo pair (``time.process_time``: what the pipeline costs this process, not
    the waits a shared machine adds to the wall clock), median over frames of each kind and over
    ``rounds`` passes, each pass a fresh pipeline: full-frame search every frame (``tracking=False``;
    all frames and those with the fingertip visible in both views), and the shipped tracking mode
    by the left view's mode of each frame (tracked window, full frame without a track, recheck);
    beside it the tracking mode with the cap fits alone (no side-edge axis), so the axis's cost is
    measured in the same run. The three configurations alternate pass by pass (a shared machine's
    load then weighs on all alike)."""
    from vishap.vision.pipeline import PipelineConfig, VisionPipeline
    from vishap.vision.stereo import RefineConfig

    gt = seq.gt
    n = len(frames)
    visible = (np.asarray(gt.get("tip_visible_left", np.ones(n, bool)))[:n].astype(bool)
               & np.asarray(gt.get("tip_visible_right", np.ones(n, bool)))[:n].astype(bool))
    out = {"clock": "process_time", "rounds": rounds, "image_size": list(seq.rig.image_size), "goals_ms": SPEED_GOALS_MS,
           "cpu_ms_per_pair": {}, "frames": {}}
    configs = (("full frame", PipelineConfig(tracking=False, learn_frames=learn)),
               ("tracked", PipelineConfig(learn_frames=learn)),
               ("cap fits only", PipelineConfig(learn_frames=learn, refine=RefineConfig(method="none"))))
    per_round: dict[str, list] = {}
    for _ in range(rounds):
        for name, cfg in configs:
            pipe = VisionPipeline(seq.rig, skin_model=skin, config=cfg)
            kinds: dict[str, list] = {}
            for i, f in enumerate(frames):
                c0 = time.process_time()
                est = pipe.process(f)
                ms = (time.process_time() - c0) * 1e3
                if est.mode == "learning":
                    continue
                if name == "full frame":
                    keys = ["full frame, all frames"] + (["full frame, fingertip visible"] if visible[i] else [])
                elif name == "tracked":
                    keys = [f"tracking on: {est.mode}"]
                else:
                    keys = [f"cap fits only (no side-edge axis): {est.mode}"]
                for k in keys:
                    kinds.setdefault(k, []).append(ms)
            for k, v in kinds.items():
                per_round.setdefault(k, []).append(float(np.median(v)))
                out["frames"][k] = len(v)
    out["cpu_ms_per_pair_rounds"] = per_round
    out["cpu_ms_per_pair"] = {k: float(np.median(v)) for k, v in per_round.items()}
    return out


def refinement_variants() -> dict:
    """The 3-D tip's variants charted against each other (speed against 3-D RMS): the masks' cap
    centres alone, with the disparity filter, with a median of 3 (paper: 5), the side-edge axis
    levelled on the cap fits (shipped; axis_disparity.AxisLevel) and as their fixed mean (before), the
    axis alone, and the stereo refinements on the images (stereo.RefineConfig) a user would pick instead."""
    from vishap.vision.pipeline import PipelineConfig
    from vishap.vision.segment import SegmentConfig
    from vishap.vision.stereo import RefineConfig

    caps = RefineConfig(method="none")
    return {
        "mask cap fits (no disparity filter)": PipelineConfig(refine=caps, disparity_q=0),
        "mask cap fits + disparity filter": PipelineConfig(refine=caps),
        "cap fits + side-edge axis levelled on them + disparity filter (shipped)": PipelineConfig(),
        "cap fits + side-edge axis, fixed mean + disparity filter (before)":
            PipelineConfig(refine=RefineConfig(method="axis", axis_level_s=0.0)),
        "cap fits + side-edge axis levelled, no disparity filter": PipelineConfig(disparity_q=0),
        "side-edge axis alone + disparity filter": PipelineConfig(refine=RefineConfig(method="axis", axis_weight=1.0,
                                                                                      axis_level_s=0.0)),
        "mask cap fits, median 3 + disparity filter": PipelineConfig(refine=caps,
                                                                     segment=SegmentConfig(coarse=4, median=3)),
        "sub-pixel image edges, a circle per view": PipelineConfig(refine=RefineConfig(method="edges_separate")),
        "sub-pixel image edges, joint fit (shared row, radius)": PipelineConfig(refine=RefineConfig(method="edges")),
        "ZNCC of the left cap along the right row": PipelineConfig(refine=RefineConfig(method="match")),
        "ZNCC, disk-masked template": PipelineConfig(refine=RefineConfig(method="match", match_masked=True)),
    }


WORKING_RANGE_M = (0.4, 0.8)  # issue 14 item 9: 3-D tip ≤ 1.5 mm RMS over this true depth


def working_range_rms(by_depth: dict | None, lo: float = WORKING_RANGE_M[0], hi: float = WORKING_RANGE_M[1]):
    """The 3-D RMS without gross errors over the depth bins of ``by_depth`` (``vishap eval vision``'s
    per-bin figures) that lie within [lo, hi) m, pooled by their frames: ``(rms_mm, frames)``."""
    num = den = 0.0
    for key, b in (by_depth or {}).items():
        a, z = (float(x) for x in key.split("-"))
        if a >= lo - 1e-9 and z <= hi + 1e-9 and b.get("tip3d_rms_mm_without_gross") is not None:
            n = b["frames"] - b["gross"]
            num += n * b["tip3d_rms_mm_without_gross"] ** 2
            den += n
    return (float(np.sqrt(num / den)) if den else None), int(den)


def _bench_refinement(folder, n, skin, quick=False, names=None):
    """Each variant of :func:`refinement_variants` over the same frames: 3-D RMS (all frames with
    the tip visible and found, and without gross errors; over the working range), the error
    decomposition by depth, ms. ``names``: only the variants whose name holds one of these words."""
    from vishap.vision.evaluate import evaluate_sequence

    out = {}
    variants = refinement_variants()
    if names:
        variants = {k: v for k, v in variants.items() if any(w in k for w in names)}
    elif quick:  # before and shipped only
        variants = {k: v for k, v in variants.items() if k.endswith(("(before)", "(shipped)"))}
    for name, cfg in variants.items():
        r = evaluate_sequence(folder, skin_model=skin, config=cfg, max_frames=n, seg_every=10 ** 9)
        out[name] = {k: r.get(k) for k in ("ms_per_pair", "ms_per_pair_tracked", "ms_per_pair_full", "tip2d_rms_px",
                                           "tip3d_rms_mm", "tip3d_rms_mm_without_gross", "gross_errors",
                                           "tip3d_median_mm", "detection_rate", "visible_frames", "by_depth")}
        out[name]["tip3d_rms_mm_working_range"], out[name]["working_range_frames"] = working_range_rms(r.get("by_depth"))
    return out


def _refinement_summary(record) -> dict:
    """Per refinement variant over the sequences: the range of the 3-D RMS without gross errors and
    of the working-range RMS, and the working-range RMS pooled over all sequences' frames."""
    per: dict[str, list] = {}
    for rec in record["sequences"].values():
        for name, r in rec.get("refinement", {}).items():
            per.setdefault(name, []).append(r)
    out = {}
    for name, rs in per.items():
        wr = [(r["tip3d_rms_mm_working_range"], r["working_range_frames"]) for r in rs
              if r.get("tip3d_rms_mm_working_range") is not None]
        wog = [r["tip3d_rms_mm_without_gross"] for r in rs if r.get("tip3d_rms_mm_without_gross") is not None]
        pooled = (float(np.sqrt(sum(v * v * k for v, k in wr) / sum(k for _, k in wr))) if wr else None)
        out[name] = {"sequences": len(rs), "without_gross_mm": [min(wog), max(wog)] if wog else None,
                     "working_range_mm": [min(v for v, _ in wr), max(v for v, _ in wr)] if wr else None,
                     "working_range_pooled_mm": pooled, "gross_errors": sum(r["gross_errors"] or 0 for r in rs),
                     "goal_mm": 1.5}
    return out


def _chart_refinement(record, path):
    """Left: one point per variant, the mean over the sequences of the 3-D RMS without gross errors
    (bar: the sequences' range) against the median of their ms per tracked pair; right: the error
    decomposition of the first sequence, before against shipped."""
    fig, (a1, a2) = new_figure(1, 2, figsize=(14, 5.5))
    seqs = {k: v for k, v in record["sequences"].items() if "refinement" in v}
    per = {}
    for rec in seqs.values():
        for name, r in rec["refinement"].items():
            x, y = r.get("ms_per_pair_tracked") or r.get("ms_per_pair"), r.get("tip3d_rms_mm_without_gross")
            if x is not None and y is not None:
                per.setdefault(name, []).append((x, y, r["gross_errors"]))
    for k, (name, v) in enumerate(per.items()):
        xs, ys, gross = (np.array(c) for c in zip(*v))
        x, y = float(np.median(xs)), float(np.mean(ys))
        a1.errorbar(x, y, yerr=[[y - ys.min()], [ys.max() - y]], fmt="os^vD<>P*Xh"[k % 10], capsize=3, color=f"C{k % 10}")
        a1.annotate(f"{name} ({len(v)} seq., {int(gross.sum())} gross)", (x, y), fontsize=7, xytext=(4, 2),
                    textcoords="offset points")
    if seqs:  # the decomposition of the first sequence: before against shipped
        sname, rec = next(iter(seqs.items()))
        pair = [n for n in rec["refinement"] if n.endswith("(before)")] + \
            [n for n in rec["refinement"] if n.endswith("(shipped)")]
        for k, name in enumerate(pair[:2]):
            bd = rec["refinement"][name]["by_depth"] or {}
            xs = np.arange(len(bd))
            for j, (key, label) in enumerate((("u_left_px", "u left"), ("u_right_px", "u right"),
                                               ("disparity_px", "disparity"))):
                a2.bar(xs + 0.13 * (3 * k + j) - 0.35, [bd[b][key] or 0 for b in bd], 0.12, color=f"C{j}",
                       hatch="//" if k else None, label=f"{label} ({'after' if k else 'before'})")
            a2.set_xticks(xs, [f"{b} m ({bd[b]['frames']} frames)" for b in bd])
        a2.set_title(f"{sname}: error decomposition by true depth (plain: before, hatched: shipped)", fontsize=9)
    a1.axhline(1.5, color="k", lw=0.6, ls=":")
    a1.set(xlabel="ms per tracked stereo pair (median over the sequences)",
           ylabel="tip 3-D RMS without gross errors, mm (mean, range)",
           title="3-D fingertip: cap fits, side-edge axis, disparity filter, stereo refinements")
    a2.set(ylabel="RMS of the reported tips, px (rectified)")
    a1.grid(alpha=0.3)
    a2.grid(alpha=0.3)
    a2.legend(fontsize=7)
    return save_figure(fig, path)


def _bench_stereo(seq, frames, skin, learn):
    from vishap.vision.pipeline import VisionPipeline
    from vishap.vision.stereo import DenseMatcher, dense_tip, triangulate_tip

    rig, gt = seq.rig, seq.gt
    pipe = VisionPipeline(rig, skin_model=skin)
    rows = []
    for i, f in enumerate(frames):
        e = pipe.process(f)
        vis = bool(gt["tip_visible_left"][i] and gt["tip_visible_right"][i]) if "tip_visible_left" in gt else True
        if e.found and vis and i >= learn:
            rows.append((f, e, gt["tip_cam"][i]))
    out = {}
    if not rows:
        return {"note": "no frame with a detected, visible tip"}
    methods = {"sparse (rectified triangulation)": lambda f, e: triangulate_tip(rig, e.uv_left, e.uv_right)}
    for m in ("bm", "sgbm"):
        dm = DenseMatcher(rig, m)
        methods[f"dense {m.upper()} (rows around the tip)"] = lambda f, e, dm=dm: dense_tip(dm, f.left, f.right, e.uv_left)
    for name, fn in methods.items():
        errs, times = [], []
        for f, e, p in rows:
            t0 = time.perf_counter()
            sp = fn(f, e)
            times.append(time.perf_counter() - t0)
            errs.append(np.linalg.norm(sp.p_cam - p) if sp.ok else np.nan)
        errs = np.array(errs)
        out[name] = {"ms_per_pair": float(np.median(times) * 1e3), "tip3d_rms_mm": float(np.sqrt(np.nanmean(errs ** 2)) * 1e3)
                     if np.any(np.isfinite(errs)) else None, "valid_fraction": float(np.mean(np.isfinite(errs)))}
    f0 = rows[0][0]
    lr, rr = rig.rectify_image(f0.left, "left"), rig.rectify_image(f0.right, "right")
    for m in ("bm", "sgbm"):
        dm = DenseMatcher(rig, m)
        out[f"dense {m.upper()} full image (paper's disparity image)"] = {
            "ms_per_pair": median_us(time_calls(lambda: dm.disparity(lr, rr), 3, warmup=1)) / 1e3}
    return out


def _bench_kalman(gt, rng):
    from vishap.vision.track import KalmanCV

    truth = np.asarray(gt["tip_uv_left"], dtype=np.float64)
    truth = truth[np.all(np.isfinite(truth), axis=1)]
    if len(truth) < 5:
        return {}
    z = truth + rng.normal(0, 0.5, truth.shape)
    dt, q, r = 1 / 30, 2e5, 0.25
    out = {}

    def run_mine():
        kf = KalmanCV(2, q=q, r=r)
        kf.reset(z[0])
        est = [z[0]]
        for zi in z[1:]:
            kf.predict(dt)
            kf.update(zi)
            est.append(kf.position.copy())
        return np.array(est)

    def run_cv2():
        kf = cv2.KalmanFilter(4, 2, 0, cv2.CV_64F)
        kf.transitionMatrix = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        kf.measurementMatrix = np.hstack([np.eye(2), np.zeros((2, 2))])
        Q = np.zeros((4, 4))
        for i in (0, 1):
            Q[np.ix_([i, i + 2], [i, i + 2])] = q * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
        kf.processNoiseCov = Q
        kf.measurementNoiseCov = np.eye(2) * r
        kf.statePost = np.array([[z[0, 0]], [z[0, 1]], [0.0], [0.0]])
        kf.errorCovPost = np.diag([4.0, 4.0, 1e4, 1e4])
        est = [z[0]]
        for zi in z[1:]:
            kf.predict()
            s = kf.correct(zi.reshape(2, 1))
            est.append(s[:2, 0].copy())
        return np.array(est)

    runners = {"this KalmanCV (NumPy)": run_mine, "cv2.KalmanFilter": run_cv2}
    try:
        from filterpy.common import Q_continuous_white_noise
        from filterpy.kalman import KalmanFilter

        def run_fp():
            kf = KalmanFilter(dim_x=4, dim_z=2)
            kf.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
            kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
            Q1 = Q_continuous_white_noise(dim=2, dt=dt, spectral_density=q)
            kf.Q = np.zeros((4, 4))
            for i in (0, 1):
                kf.Q[np.ix_([i, i + 2], [i, i + 2])] = Q1
            kf.R = np.eye(2) * r
            kf.x = np.array([z[0, 0], z[0, 1], 0.0, 0.0])
            kf.P = np.diag([4.0, 4.0, 1e4, 1e4])
            est = [z[0]]
            for zi in z[1:]:
                kf.predict()
                kf.update(zi)
                est.append(kf.x[:2].copy())
            return np.array(est)

        runners["filterpy"] = run_fp
    except ImportError:
        pass
    ref = run_mine()
    for name, fn in runners.items():
        est = fn()
        dts = time_calls(fn, 5, warmup=1)
        out[name] = {"us_per_step": float(np.median(dts) / (len(z) - 1) * 1e6),
                     "rms_px": float(np.sqrt(np.mean((est - truth) ** 2))),
                     "max_diff_from_this_px": float(np.max(np.abs(est - ref)))}
    out["raw measurements"] = {"us_per_step": 0.0, "rms_px": float(np.sqrt(np.mean((z - truth) ** 2)))}
    return out


def _capsule(c, ang, R, shape=(160, 160), ss=4):
    """Anti-aliased mask of a finger (cap centre ``c``, radius ``R`` px) pointing away from ``ang``."""
    H, W = shape
    yy, xx = (np.mgrid[0:H * ss, 0:W * ss].astype(float) + 0.5) / ss - 0.5
    d = np.array([np.cos(ang), np.sin(ang)])
    rel = np.stack([xx - c[0], yy - c[1]], -1)
    q = rel - np.clip(rel @ d, 0, 300.0)[..., None] * d
    cov = (np.hypot(q[..., 0], q[..., 1]) <= R).reshape(H, ss, W, ss).mean((1, 3))
    return (cov >= 0.5).astype(np.uint8) * 255


def _bench_detector_constants(rng, n=40):
    """Detection rate and cap-centre error of the paper's detector for several (r/R, δr/r) choices,
    against the error of the depth used for r = K/z (scale of the true radius over the assumed)."""
    from vishap.vision.fingertip import FingertipConfig, detect_fingertip

    cases = []
    for _ in range(n):
        c, ang, R = rng.uniform(70, 90, 2), rng.uniform(-np.pi, np.pi), rng.uniform(5, 10)
        cases.append((c, R, _capsule(c, ang, R)))
    scales = [0.8, 0.85, 0.92, 1.0, 1.08, 1.15, 1.25]
    out = {}
    for ratio, dfrac in ((0.6, 0.8), (0.75, 0.35), (0.7, 0.45), (0.9, 0.2), (0.5, 0.6)):
        rows = []
        for sc in scales:
            ok, err = 0, []
            for c, R, m in cases:
                t = detect_fingertip(m, ratio * R / sc, FingertipConfig(delta_r_frac=dfrac))
                if t.found and np.hypot(*(t.uv - c)) < 1.5:
                    ok += 1
                    err.append(np.hypot(*(t.uv - c)))
            rows.append({"radius_scale": sc, "detection_rate": ok / n,
                         "rms_px": float(np.sqrt(np.mean(np.square(err)))) if err else None})
        out[f"r={ratio}R, dr={dfrac}r (square {ratio * (1 + dfrac):.2f}R)"] = rows
    return out


def _chart_constants(rec, path):
    fig, ax = new_figure(1, 1, figsize=(7, 4.5))
    for name, rows in rec.items():
        ax.plot([r["radius_scale"] for r in rows], [r["detection_rate"] for r in rows], "o-", label=name)
    ax.set(xlabel="true cap radius / radius implied by the depth used", ylabel="detection rate (within 1.5 px)",
           title="Paper's detector: circle radius and square size (paper gives no values)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def run(args: argparse.Namespace) -> dict:
    from vishap._core.errors import ConfigError
    from vishap.vision.skin_model import SkinModel

    stages = [s.strip() for s in str(getattr(args, "stages", None) or ",".join(STAGES)).split(",") if s.strip()]
    unknown = [s for s in stages if s not in STAGES]
    if unknown:
        raise ConfigError(f"--stages: unknown stage(s) {', '.join(unknown)}; expected some of {', '.join(STAGES)}",
                          field="stages")
    variants = getattr(args, "variants", None)
    rounds = getattr(args, "rounds", None) or (1 if args.quick else 3)
    out_dir = Path(args.out)
    skin = SkinModel.load(args.skin) if args.skin else SkinModel.load()
    rng = np.random.default_rng(0)
    record = {"machine": machine_info(), "cv2_threads": cv2.getNumThreads(), "stages": stages, "sequences": {}}
    per_seq = [s for s in stages if s != "constants"]
    with tempfile.TemporaryDirectory() as tmp:
        from vishap._core.results import progress

        folders = [Path(d) for d in args.data] if args.data else _default_data(Path(tmp))
        bar = progress(total=len(per_seq) * len(folders), desc="bench vision", unit="stage",
                       quiet=getattr(args, "quiet", False))
        for folder in folders:
            seq, frames = _load(folder, args.frames)
            learn = int(seq.gt.get("hand_free_frames", 10))
            if len(frames) < learn + 5:
                record["sequences"][folder.name] = {"skipped": f"{len(frames)} frames: fewer than {learn} background + 5"}
                bar.update(len(per_seq))
                continue
            rec = {"frames": len(frames), "skin_model": skin.source}
            measures = {"pipeline": lambda: _bench_pipeline(folder, args.frames, skin),
                        "refinement": lambda: _bench_refinement(folder, args.frames, skin, args.quick, variants),
                        "segmentation": lambda: _bench_segmentation(frames, learn, skin, args.quick),
                        "stereo": lambda: _bench_stereo(seq, frames, skin, learn),
                        "kalman": lambda: _bench_kalman(seq.gt, rng),
                        "speed": lambda: _bench_speed(seq, frames, skin, learn, rounds)}
            for stage in per_seq:
                bar.set_postfix_str(f"{folder.name}: {stage}")
                rec[stage] = measures[stage]()
                bar.update(1)
            record["sequences"][folder.name] = rec
        bar.close()
    if "refinement" in stages:
        record["refinement_summary"] = _refinement_summary(record)
    if any(s in stages for s in ("segmentation", "pipeline", "stereo", "kalman")):
        record["chart"] = str(_chart(record, out_dir / "vision_speed_accuracy.png"))
    if "refinement" in stages:
        record["chart_refinement"] = str(_chart_refinement(record, out_dir / "vision_stereo_refinement.png"))
    if "constants" in stages:
        record["detector_constants"] = _bench_detector_constants(rng)
        record["chart_detector_constants"] = str(_chart_constants(record["detector_constants"],
                                                                  out_dir / "vision_detector_constants.png"))
    return record


def _chart(record, path):
    fig, axes = new_figure(2, 2, figsize=(13, 9))
    (a1, a2), (a3, a4) = axes
    seqs = {k: v for k, v in record["sequences"].items() if "skipped" not in v}
    multi = len(seqs) > 1
    for sname, rec in seqs.items():
        tag = f"{sname}: " if multi else ""
        for name, r in rec.get("segmentation", {}).items():
            mk = {"variant": "o", "backend": "s", "peer": "^"}[r["kind"]]
            a1.scatter(r["ms_per_image"], 100 * r["seg_correct"], marker=mk)
            a1.annotate(f"{tag}{name}", (r["ms_per_image"], 100 * r["seg_correct"]), fontsize=7)
        for name, r in rec.get("pipeline", {}).items():
            if r["ms_per_pair"] is not None and r["tip3d_rms_mm"] is not None:
                a2.scatter(r["ms_per_pair"], r["tip3d_rms_mm"])
                a2.annotate(f"{tag}{name} (det {r['detection_rate']:.2f})", (r["ms_per_pair"], r["tip3d_rms_mm"]), fontsize=7)
        for name, r in rec.get("stereo", {}).items():
            if isinstance(r, dict) and r.get("tip3d_rms_mm") is not None:
                a3.scatter(r["ms_per_pair"], r["tip3d_rms_mm"])
                a3.annotate(f"{tag}{name} (valid {r['valid_fraction']:.2f})", (r["ms_per_pair"], r["tip3d_rms_mm"]), fontsize=7)
        for name, r in rec.get("kalman", {}).items():
            a4.scatter(max(r["us_per_step"], 0.1), r["rms_px"])
            a4.annotate(tag + name, (max(r["us_per_step"], 0.1), r["rms_px"]), fontsize=7)
    a1.set(xscale="log", xlabel="ms per 640×480 image (median)", ylabel="segmentation correct, %",
           title="Segmentation: variants, torch backend (■), OpenCV subtractors (▲)")
    a2.set(xlabel="ms per stereo pair (median)", ylabel="tip 3-D RMS, mm", title="Pipeline modes")
    a3.set(xscale="log", xlabel="ms per pair", ylabel="tip 3-D RMS, mm", title="Stereo: sparse vs dense")
    a4.set(xscale="log", xlabel="µs per predict+update", ylabel="RMS vs truth, px", title="Kalman filters")
    for a in (a1, a2, a3, a4):
        a.grid(alpha=0.3)
    return save_figure(fig, path)
