"""``vishap bench learned``: the learned hand-landmark detector and the hybrid on real photos and video.

* **photos**: every labelled real photo as an independent frame (each detector reset before each):
  detection rate, PCK@10/20/30 and median error of ``tip_end_uv`` against the annotated tip, the
  same for ``cap_uv``, and the median time per frame, for ``learned`` (palm + landmark networks on
  the full frame) and ``hybrid`` (the same, then the geometric cap fit), and, as the "before" of
  the same run, ``learned_mediapipe_palm_rule`` (MediaPipe's choice of the hand: the best palm box
  on the letterboxed frame if it scores ≥ 0.5; ``vishap.vision.learned.MEDIAPIPE_PALM_RULE``);
* **video**: the photos in file order as one 30 fps video (the train split is made of consecutive
  frames of short clips, with a jump to another moment about every 11 frames), the detectors
  interleaved frame by frame so they share the machine's load (in a new random order on each frame): ``learned`` (image mode),
  ``learned_video`` (MediaPipe's video mode: the landmark network on the region the last landmarks
  give, the palm network only when that loses the hand) and ``hybrid`` (window tracking between
  re-checks), plus the hybrid's re-check interval swept, and the "before" of the same run:
  ``learned_video_mediapipe_palm_rule`` and ``hybrid_before`` (that palm rule, and the patch
  follower with no limit on its run of frames); ``hybrid_no_cut_check`` (no scene-cut check) and
  ``hybrid_cap_end_no_cut_check`` (neither that nor the annotation's tip point: ``tip_end_uv`` at the
  cap's end, landmark 8 where no cap fit; ``hybrid_cap_end`` among the photos) show what each
  of the hybrid's earlier changes buys, and ``hybrid_no_window_checks`` (no skin check on a patch
  match, no check of a cap fit against the track) what those do (on independent photos the
  window never runs, so the photos have no such row); ``hybrid_no_reread_no_jump`` (no second
  landmark reading of a find no cap fit confirms, no re-check on a cap fit that jumps from the
  prediction) what its latest do, on photos, video and moving photos;
* **peer** (``--mediapipe-task FILE``, where the ``mediapipe`` package is importable, e.g. in a separate
  environment): MediaPipe's own HandLandmarker in image and video mode beside them;
* **fit replays**: the fit split played every 2nd photo (from the 1st and from the 2nd), every
  3rd and backwards (``--fit-orders``): faster motion and more cuts than the file order, from the
  photos tuning may look at; the hybrid with and without its window checks, ``learned_video`` and
  MediaPipe's video mode where it runs. The frames beyond 30 px are listed by photo;
* **moving photo**: a few photos moved along a smooth path (a video whose every frame has a known
  tip): the per-frame time of ``learned_video`` against the hybrid in pure tracking mode, and how
  well the tracked tip follows the motion.

Every score is also given on the *fit* split (photos 1…``--fit-last`` in file order, the only
ones looked at while tuning) and on the *held-out* rest (``fit`` / ``held_out``), and
``annotation_along_finger`` says where the annotation lies along the finger relative to the
hybrid's cap, per split, for a fitted cap and for the landmarks' cap (on the fit split: the
hybrid's ``tip_end_frac`` and ``landmark_tip_end_frac``).

Writes ``learned.json`` and ``learned_speed_accuracy.png`` (ms per frame against PCK@20/30).
"""
from __future__ import annotations

import argparse
import csv
from pathlib import Path

import cv2
import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "learned hand-landmark detector and the hybrid: PCK and ms/frame on real photos and video"
QUICK_ARGS = ["--every", "10", "--moving-photos", "2"]

_DEFAULT_DATA = Path(__file__).resolve().parents[2].parent / "shared" / "real" / "ti1k-train"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", default=str(_DEFAULT_DATA),
                   help="folder with images/ and labels.csv (frame,u,v); default: the real train photos beside the repository")
    p.add_argument("--every", type=int, default=1, help="use every k-th photo (default 1: all)")
    p.add_argument("--fit-last", type=int, default=600,
                   help="photos 1..N (file order) are the fit split (tuned on), the rest held out (default 600)")
    p.add_argument("--recheck", default="3,5,10,20", help="hybrid re-check intervals to sweep on the video")
    p.add_argument("--fit-orders", default="2,2b,3,r",
                   help="replays of the fit split: 2 (every 2nd photo), 2b (every 2nd from the 2nd), 3 (every 3rd), "
                        "r (backwards); empty: none")
    p.add_argument("--moving-photos", type=int, default=5, help="photos turned into moving-image videos (default 5)")
    p.add_argument("--moving-frames", type=int, default=60, help="frames per moving-image video (default 60)")
    p.add_argument("--mediapipe-task", default=None,
                   help="a hand_landmarker.task bundle: also run MediaPipe's own HandLandmarker (image and video "
                        "mode) as the peer, where the mediapipe package is importable (it is not a dependency)")


def _load_labels(folder: Path, every: int) -> list[tuple[Path, np.ndarray | None, int]]:
    """(image path, annotated tip or None, 0-based row of labels.csv) of every ``every``-th row."""
    from vishap._core.errors import ConfigError

    path = folder / "labels.csv"
    if not path.is_file():
        raise ConfigError(f"no labels.csv in {folder}", file=path)
    out = []
    with open(path, newline="") as f:
        for i, row in enumerate(csv.DictReader(f)):
            if not {"frame", "u", "v"} <= set(row):
                raise ConfigError("expected columns frame,u,v", file=path, field=f"row {i + 2}")
            uv = None if not row["u"] or not row["v"] else np.array([float(row["u"]), float(row["v"])])
            out.append((folder / "images" / row["frame"], uv, i))
    return out[::max(1, every)]


def _read(path: Path) -> np.ndarray:
    from vishap._core.errors import VisionError

    img = cv2.imread(str(path))
    if img is None:
        raise VisionError(f"{path}: cannot read image")
    return img


def _scores(results: list[dict], fit_last: int | None = None) -> dict:
    """PCK, detection rate, errors and time over per-frame results {found, tip, cap, gt, ms, row};
    with ``fit_last``, also the PCK and detection rate of rows < ``fit_last`` (``fit``) and of the
    rest (``held_out``)."""
    lab = [r for r in results if r["gt"] is not None]
    tip = np.array([np.hypot(*(r["tip"] - r["gt"])) if r["found"] else np.inf for r in lab])
    cap = np.array([np.hypot(*(r["cap"] - r["gt"])) if r["found"] else np.inf for r in lab])
    ms = np.array([r["ms"] for r in results])
    out = {"frames": len(results), "detection_rate": float(np.mean([r["found"] for r in lab])) if lab else None}
    for k in (10, 20, 30):
        out[f"pck_{k}"] = float(np.mean(tip <= k))
    out["median_error_px"] = float(np.median(tip))
    for k in (10, 20, 30):
        out[f"cap_pck_{k}"] = float(np.mean(cap <= k))
    out["cap_median_error_px"] = float(np.median(cap))
    out["ms_per_frame"] = float(np.median(ms))
    out["ms_per_frame_mean"] = float(np.mean(ms))
    out["ms_per_frame_p90"] = float(np.percentile(ms, 90))
    modes: dict = {}
    for r in results:
        modes[r["mode"]] = modes.get(r["mode"], 0) + 1
    out["modes"] = modes
    if fit_last is not None:
        for split, part in _split(results, fit_last).items():
            if any(r["gt"] is not None for r in part):
                sc = _scores(part)
                out[split] = {k: sc[k] for k in ("frames", "detection_rate", "pck_10", "pck_20", "pck_30",
                                                 "median_error_px", "cap_pck_30")}
    return out


def _beyond(results: list[dict], px: float = 30.0) -> list[int]:
    """Photo numbers (1-based rows of labels.csv) of the labelled frames with no output within ``px``."""
    return [r["row"] + 1 for r in results if r["gt"] is not None
            and (not r["found"] or float(np.hypot(*(r["tip"] - r["gt"]))) > px)]


def _step(det, img, t, gt, row: int) -> dict:
    d = det.process(img, t)
    return {"found": d.found, "tip": d.tip_end_uv, "cap": d.cap_uv, "gt": gt, "mode": d.mode, "row": row,
            "radius": d.radius_px, "direction": d.direction, "ms": d.timings.get("total_ms", np.nan)}


def _shuffled(dets: dict, rng: np.random.Generator) -> list:
    """The detectors' (name, detector) pairs in a random order. Interleaved frame by frame, the
    detector that runs right after a network finds the caches cold (the hybrid on moving photos, two
    runs with the order swapped: median 1.05–1.35 ms there, 0.70–0.86 ms elsewhere); a fixed or
    merely rotated order would give each detector the same predecessor on every frame."""
    items = list(dets.items())
    return [items[j] for j in rng.permutation(len(items))]


def _label_offset(results: list[dict], mode: str = "learned+refine") -> dict:
    """Where the annotation lies along the finger, relative to the hybrid's cap in frames of ``mode``
    (``learned+refine``: a fitted cap; ``learned``: the landmarks' cap): ``(gt − cap)·(−direction)``
    in cap radii (1: the fingertip's end; 0: the cap centre)."""
    off = [float((r["gt"] - r["cap"]) @ -r["direction"]) / r["radius"] for r in results
           if r["mode"] == mode and r["gt"] is not None and r["radius"] > 0]
    if not off:
        return {"frames": 0}
    return {"frames": len(off), "median_radii": float(np.median(off)),
            "quartiles_radii": [float(np.percentile(off, 25)), float(np.percentile(off, 75))]}


def _label_offsets(results: list[dict], fit_last: int) -> dict:
    """:func:`_label_offset` per split (fit: rows < ``fit_last``) and per cap (fitted, landmarks')."""
    return {split: {"fitted_cap": _label_offset(part, "learned+refine"), "landmark_cap": _label_offset(part, "learned")}
            for split, part in _split(results, fit_last).items()}


def _split(results: list[dict], fit_last: int) -> dict[str, list[dict]]:
    """The per-frame results of the fit split (rows < ``fit_last``) and the held-out one."""
    return {"fit": [r for r in results if r["row"] < fit_last], "held_out": [r for r in results if r["row"] >= fit_last]}


def _moving_frames(img: np.ndarray, gt: np.ndarray, n: int, seed: int):
    """``n`` frames of ``img`` moved along a smooth random path (≤ ~4 px per frame), with the tip."""
    rng = np.random.default_rng(seed)
    a, w, ph = rng.uniform(20, 40, 2), rng.uniform(0.05, 0.1, 2), rng.uniform(0, 2 * np.pi, 2)
    h, wd = img.shape[:2]
    for k in range(n):
        s = a * (np.sin(w * k + ph) - np.sin(ph))
        m = np.float32([[1, 0, s[0]], [0, 1, s[1]]])
        yield cv2.warpAffine(img, m, (wd, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT), gt + s


class _MediaPipePeer:
    """MediaPipe's HandLandmarker (the ``mediapipe`` package) as a mono detector, for the chart only."""

    def __init__(self, task: str, mode: str):
        import mediapipe as mp
        from mediapipe.tasks import python as mpt
        from mediapipe.tasks.python import vision

        self._mp, self._vision, self._mode = mp, vision, mode
        running = vision.RunningMode.IMAGE if mode == "image" else vision.RunningMode.VIDEO
        self._opts = vision.HandLandmarkerOptions(base_options=mpt.BaseOptions(model_asset_path=task),
                                                  num_hands=1, running_mode=running)
        self.name = f"mediapipe_{mode}"
        self.reset()

    def reset(self) -> None:
        if self._mode == "video" or not hasattr(self, "_lm"):  # image mode keeps no state between frames
            self._lm = self._vision.HandLandmarker.create_from_options(self._opts)
        self._t_ms = -1

    def process(self, image, t):
        import time

        from vishap.vision.detector import MonoDetection
        from vishap.vision.learned import INDEX_TIP, cap_from_landmarks

        t0 = time.perf_counter()
        im = self._mp.Image(image_format=self._mp.ImageFormat.SRGB, data=cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
        if self._mode == "image":
            out = self._lm.detect(im)
        else:  # timestamps must increase
            self._t_ms = max(self._t_ms + 1, int(round(t * 1000)))
            out = self._lm.detect_for_video(im, self._t_ms)
        ms = 1e3 * (time.perf_counter() - t0)
        if not out.hand_landmarks:
            return MonoDetection(t, False, mode=self.name, timings={"total_ms": ms})
        h, w = image.shape[:2]
        uvz = np.array([[p.x * w, p.y * h, p.z * w] for p in out.hand_landmarks[0]])
        cap, r, d = cap_from_landmarks(uvz)
        return MonoDetection(t, True, tip_end_uv=uvz[INDEX_TIP, :2], cap_uv=cap, radius_px=r, direction=d,
                             mode=self.name, timings={"total_ms": ms})


def _mediapipe_peers(task: str | None) -> dict:
    if not task:
        return {}
    try:
        return {"mediapipe_image": _MediaPipePeer(task, "image"), "mediapipe_video": _MediaPipePeer(task, "video")}
    except ImportError:
        print("mediapipe not importable: MediaPipe's own HandLandmarker left out")
        return {}


def run(args: argparse.Namespace) -> dict:
    from vishap.vision import learned as L
    from vishap.vision.hybrid import HybridConfig, HybridDetector

    if not L.runtime_available():
        print(L.INSTALL_HINT)
        return {"available": False, "reason": L.INSTALL_HINT}
    out = Path(args.out)
    items = _load_labels(Path(args.data), args.every)
    fit_last = int(getattr(args, "fit_last", 600))
    dt = 1 / 30
    # the hybrid before its scene-cut check and the annotation's tip point (tip_end_uv at the cap's end)
    no_cut, cap_end = dict(cut_ncc=None), dict(tip_end_frac=1.0, landmark_tip_end_frac=None)
    no_checks = dict(template_min_skin=None, disagree_radius_ratio=None)  # the window's checks off
    # the hybrid before its re-read of an unconfirmed find and its jump re-check
    no_reread = dict(max_rereads=0, recheck_jump_radii=None)

    def make(kind: str, before: bool = False, **options):
        # before=True: MediaPipe's palm rule (best box ≥ 0.5, one zoom), and for the hybrid the patch
        # follower without a limit on its run: the detectors as they were before the hand recovery
        lc = L.LearnedConfig(mode="video" if kind == "hybrid" else kind, **(L.MEDIAPIPE_PALM_RULE if before else {}))
        if kind == "hybrid":
            if before:
                options.setdefault("max_template_run", 10 ** 6)
            return HybridDetector(HybridConfig(**options), learned=L.LearnedDetector(lc))
        return L.LearnedDetector(lc)

    # ---------------------------------------------------------------- photos
    peers = _mediapipe_peers(getattr(args, "mediapipe_task", None))
    photo_dets = {"learned": make("image"), "hybrid": make("hybrid"), "hybrid_cap_end": make("hybrid", **cap_end),
                  "learned_mediapipe_palm_rule": make("image", before=True),
                  "hybrid_no_reread_no_jump": make("hybrid", **no_reread)}
    if peers:
        photo_dets["mediapipe_image"] = peers["mediapipe_image"]
    from vishap._core.results import progress

    quiet = getattr(args, "quiet", False)
    photo = {k: [] for k in photo_dets}
    rng = np.random.default_rng(0)  # the detectors' order on each frame
    for path, gt, row in progress(items, desc="bench learned: photos", unit="photo", quiet=quiet):
        img = _read(path)
        for name, det in _shuffled(photo_dets, rng):
            det.reset()
            photo[name].append(_step(det, img, 0.0, gt, row))
    photos = {k: _scores(v, fit_last) for k, v in photo.items()}

    # ---------------------------------------------------------------- video: the photos in order
    recheck = [int(x) for x in str(args.recheck).split(",") if x]
    video_dets = {"learned": make("image"), "learned_video": make("video"), "hybrid": make("hybrid"),
                  "learned_video_mediapipe_palm_rule": make("video", before=True),
                  "hybrid_before": make("hybrid", before=True), "hybrid_no_cut_check": make("hybrid", **no_cut),
                  "hybrid_cap_end_no_cut_check": make("hybrid", **no_cut, **cap_end),
                  "hybrid_no_window_checks": make("hybrid", **no_checks),
                  "hybrid_no_reread_no_jump": make("hybrid", **no_reread)}
    if peers:
        video_dets["mediapipe_video"] = _MediaPipePeer(args.mediapipe_task, "video")
    for n in recheck:
        if n != HybridConfig().recheck_every:
            video_dets[f"hybrid_recheck_{n}"] = make("hybrid", recheck_every=n)
    video = {k: [] for k in video_dets}
    for i, (path, gt, row) in enumerate(progress(items, desc="bench learned: video", unit="frame", quiet=quiet)):
        img = _read(path)
        for name, det in _shuffled(video_dets, rng):
            video[name].append(_step(det, img, i * dt, gt, row))
    videos = {k: {**_scores(v, fit_last), "beyond_30px": _beyond(v)} for k, v in video.items()}

    # ---------------------------------------------------------------- the fit split replayed
    fit_items = [it for it in items if it[2] < fit_last]
    orders = {"2": fit_items[::2], "2b": fit_items[1::2], "3": fit_items[::3], "r": fit_items[::-1]}
    replay_names = {"2": "every_2nd", "2b": "every_2nd_from_2nd", "3": "every_3rd", "r": "backwards"}
    replays = {}
    for key in [k for k in str(getattr(args, "fit_orders", "")).split(",") if k]:
        if key not in orders:
            from vishap._core.errors import ConfigError

            raise ConfigError(f"--fit-orders: unknown replay {key!r} (expected 2, 2b, 3 or r)", field="fit_orders")
        rp_dets = {"hybrid": make("hybrid"), "hybrid_no_window_checks": make("hybrid", **no_checks),
                   "hybrid_no_reread_no_jump": make("hybrid", **no_reread),
                   "learned_video": make("video")}
        if peers:
            rp_dets["mediapipe_video"] = _MediaPipePeer(args.mediapipe_task, "video")
        rp = {k: [] for k in rp_dets}
        for i, (path, gt, row) in enumerate(progress(orders[key], desc=f"bench learned: fit {replay_names[key]}",
                                                     unit="frame", quiet=quiet)):
            img = _read(path)
            for name, det in _shuffled(rp_dets, rng):
                rp[name].append(_step(det, img, i * dt, gt, row))
        replays[replay_names[key]] = {k: {**_scores(v), "beyond_30px": _beyond(v)} for k, v in rp.items()}

    # ---------------------------------------------------------------- moving photos
    labelled = [(p, g, row) for p, g, row in items if g is not None]
    picks = [labelled[int(j)] for j in np.linspace(0, len(labelled) - 1, max(0, args.moving_photos), dtype=int)] \
        if labelled and args.moving_photos > 0 else []
    mv_dets = {"learned_video": make("video"), "hybrid": make("hybrid"),
               "hybrid_cap_end_no_cut_check": make("hybrid", **no_cut, **cap_end),
               "hybrid_no_window_checks": make("hybrid", **no_checks),
               "hybrid_no_reread_no_jump": make("hybrid", **no_reread)}
    if peers:
        mv_dets["mediapipe_video"] = _MediaPipePeer(args.mediapipe_task, "video")
    moving = {k: [] for k in mv_dets}
    for j, (path, gt, row) in enumerate(progress(picks, desc="bench learned: moving photos", unit="photo", quiet=quiet)):
        for det in mv_dets.values():
            det.reset()
        for k, (frame, gt_k) in enumerate(_moving_frames(_read(path), gt, args.moving_frames, seed=j)):
            for name, det in _shuffled(mv_dets, rng):
                moving[name].append(_step(det, frame, k * dt, gt_k, row))
    movings = {k: _scores(v, fit_last) for k, v in moving.items() if v}
    tracked_ms = [r["ms"] for r in moving["hybrid"] if r["mode"] == "tracked"]
    if movings:
        movings["hybrid"]["tracked_ms_per_frame"] = float(np.median(tracked_ms)) if tracked_ms else None

    def ratio(rec: dict, a: str, b: str, key: str):
        return rec[a][key] / rec[b][key] if a in rec and b in rec and rec[b][key] else None

    record = {
        "data": str(args.data),
        "photos": photos,
        "fit_last": fit_last,
        "annotation_along_finger": _label_offsets(photo["hybrid"], fit_last),
        "video": videos,
        "fit_replays": replays,
        "moving_photo": movings,
        "hybrid_over_learned_video_time": {
            "video_median": ratio(videos, "hybrid", "learned_video", "ms_per_frame"),
            "video_mean": ratio(videos, "hybrid", "learned_video", "ms_per_frame_mean"),
            "moving_photo_median": ratio(movings, "hybrid", "learned_video", "ms_per_frame"),
            "moving_photo_mean": ratio(movings, "hybrid", "learned_video", "ms_per_frame_mean"),
        },
        "hybrid_over_mediapipe_video_time": {
            "video_median": ratio(videos, "hybrid", "mediapipe_video", "ms_per_frame"),
            "video_mean": ratio(videos, "hybrid", "mediapipe_video", "ms_per_frame_mean"),
            "moving_photo_median": ratio(movings, "hybrid", "mediapipe_video", "ms_per_frame"),
            "moving_photo_mean": ratio(movings, "hybrid", "mediapipe_video", "ms_per_frame_mean"),
            "moving_photo_mean_before": ratio(movings, "hybrid_cap_end_no_cut_check", "mediapipe_video",
                                              "ms_per_frame_mean"),
            "moving_photo_mean_no_window_checks": ratio(movings, "hybrid_no_window_checks", "mediapipe_video",
                                                        "ms_per_frame_mean"),
            "video_mean_no_window_checks": ratio(videos, "hybrid_no_window_checks", "mediapipe_video",
                                                 "ms_per_frame_mean"),
            "moving_photo_mean_no_reread_no_jump": ratio(movings, "hybrid_no_reread_no_jump", "mediapipe_video",
                                                         "ms_per_frame_mean"),
            "video_mean_no_reread_no_jump": ratio(videos, "hybrid_no_reread_no_jump", "mediapipe_video",
                                                  "ms_per_frame_mean"),
        } if peers else None,
        "hybrid_over_learned_time": {
            "video_mean": ratio(videos, "hybrid", "learned", "ms_per_frame_mean"),
            "photos_median": ratio(photos, "hybrid", "learned", "ms_per_frame"),
        },
        "machine": machine_info(),
        "num_threads": L.LearnedConfig().num_threads,
    }
    _chart(record, out / "learned_speed_accuracy.png")
    return record


def _chart(rec: dict, path: Path) -> None:
    fig, axes = new_figure(1, 3, figsize=(15, 4.6))
    panels = (("photos (independent)", rec["photos"], "ms_per_frame"),
              ("video: train photos in order", rec["video"], "ms_per_frame_mean"),
              ("moving photo (pure tracking)", rec["moving_photo"], "ms_per_frame_mean"))
    for ax, (title, group, key) in zip(axes, panels):
        for name, s in group.items():
            for k, marker in ((20, "o"), (30, "s")):
                ax.scatter(s[key], s[f"pck_{k}"], marker=marker, color=_colour(name))
            ax.annotate(name, (s[key], s["pck_20"]), textcoords="offset points", xytext=(4, -10), fontsize=7)
        from matplotlib.ticker import NullFormatter, ScalarFormatter

        ax.set_xscale("log")
        xs = [s[key] for s in group.values()]
        if xs:
            ax.set_xlim(min(xs) / 2, max(xs) * 2)
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("ms per frame (" + ("median" if key == "ms_per_frame" else "mean, re-checks included") + ")")
        ax.set_ylabel("PCK (o: 20 px, s: 30 px) of tip_end_uv")
        ax.set_ylim(0, 1.02)
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path)


def _colour(name: str) -> str:
    if name.startswith("hybrid_recheck"):
        return "tab:orange"
    if name.endswith(("_palm_rule", "_before", "_cap_end", "_no_cut_check", "_no_window_checks", "_no_reread_no_jump")):
        return "tab:gray"
    return {"learned": "tab:blue", "learned_video": "tab:purple", "hybrid": "tab:red",
            "mediapipe_image": "tab:green", "mediapipe_video": "tab:olive"}.get(name, "grey")
