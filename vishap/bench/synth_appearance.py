"""``vishap bench synth_appearance``: skin at the fingertip, real photos against our renders.

Real: the pixels just inside the annotated fingertip of the TI1K train photos 1…``--fit-last``
(the fit split; the held-out photos are not read): a stroke from the tip end toward the hand box's
centre over 5 % of the box's diagonal (:func:`vishap.vision.skin_hist.weak_skin_labels`).
Renders: the skin-labelled pixels inside the fingertip cap's disc (projected cap centre, radius
f·r/z) of the left view, wall script, ``--seeds`` sequences × ``--frames`` frames while the hand
works, camera effects on (what the vision benches see), for each look: the plain look (the
default), the real skin look on the default backgrounds, and the real skin look on a real
photograph. Reported: HSV percentiles (OpenCV 8-bit), the share under the paper's saturation
gate of 40, the share of clipped values (V ≥ 250), the 1-D Wasserstein distance of each channel to
the real pixels, and the median render time per pair of each look (rendered interleaved, same
frames). Chart: the three histograms, real against each look.
"""
from __future__ import annotations

import argparse
import os
import re
import time
from pathlib import Path

import cv2
import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "skin HSV at the fingertip: real photos (fit split) vs renders, plain and real look -> JSON + chart"
QUICK_ARGS = ["--seeds", "6", "--every", "4", "--resolution", "320x240"]

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run", "real_tip_hsv", "render_tip_hsv", "LOOKS"]

#: look name → (skin_tone, background) of the sequence spec
LOOKS = {"plain (default)": (None, "auto"), "real skin": ("real", "auto"), "real skin + photo": ("real", "photo")}
_TIP_STROKE = 0.05   # fraction of the box diagonal: the fingertip's own pixels
_S_GATE = 40         # the paper's saturation gate


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", default=os.environ.get("VISHAP_REAL_DATA", "../shared/real/ti1k-train"),
                   help="real data folder with images/ and labels.csv (default: $VISHAP_REAL_DATA or ../shared/real/ti1k-train)")
    p.add_argument("--fit-last", type=int, default=600, help="use photos 1..N only (the fit split; default 600)")
    p.add_argument("--every", type=int, default=1, help="every N-th of those photos (default 1)")
    p.add_argument("--seeds", type=int, default=24, help="rendered sequences per look (default 24)")
    p.add_argument("--frames", type=int, default=3, help="frames per sequence (1 s apart from t = 1 s; default 3)")
    p.add_argument("--resolution", default="640x480", help="render size WxH (default 640x480)")


def real_tip_hsv(data: Path, fit_last: int, every: int = 1) -> tuple[np.ndarray, int]:
    """HSV (n, 3) uint8 of the fingertip pixels of photos 1..fit_last, and the photo count."""
    from vishap.vision.skin_hist import read_annotations, weak_skin_labels

    rows = []
    for row in read_annotations(data / "labels.csv"):
        digits = re.findall(r"\d+", Path(row["frame"]).stem)
        if row["tip"] is not None and row["box"] is not None and digits and int(digits[-1]) <= fit_last:
            rows.append(row)
    rows = rows[:: max(1, every)]
    out = []
    for row in rows:
        img = cv2.imread(str(data / "images" / row["frame"]), cv2.IMREAD_COLOR)
        if img is None:
            from vishap._core.errors import ConfigError

            raise ConfigError(f"frame {row['frame']!r}: cannot read the image", file=data / "labels.csv")
        skin, _ = weak_skin_labels(img.shape, row["tip"], None, row["box"], stroke_frac=_TIP_STROKE)
        out.append(cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[skin])
    return (np.concatenate(out) if out else np.zeros((0, 3), np.uint8)), len(rows)


def render_tip_hsv(pair, row, rig) -> np.ndarray:
    """HSV of the skin pixels inside the fingertip cap's disc in the left view (empty if hidden)."""
    from vishap.sim.state import TIP_RADIUS_M

    if not row["tip_visible_left"]:
        return np.zeros((0, 3), np.uint8)
    u, v = row["tip_uv_left"]
    r = rig.K_left[0, 0] * TIP_RADIUS_M / float(row["tip_cam"][2])
    h, w = pair.labels_left.shape
    yy, xx = np.mgrid[0:h, 0:w]
    m = ((xx - u) ** 2 + (yy - v) ** 2 <= r * r) & (pair.labels_left == 1)
    return cv2.cvtColor(pair.left, cv2.COLOR_BGR2HSV)[m]


def _renders(seeds: int, frames: int, width: int, height: int) -> dict:
    """Tip HSV and ms per pair of every look; the looks are rendered interleaved, frame by frame."""
    from vishap.sim.sequence import SequenceSpec, make_renderer, prepare, render_frames

    px = {k: [] for k in LOOKS}
    ms = {k: [] for k in LOOKS}
    n_frames = {k: 0 for k in LOOKS}
    for seed in range(seeds):
        preps, rends = {}, {}
        for k, (tone, bg) in LOOKS.items():
            spec = SequenceSpec(scene="wall", frames=frames, seed=seed, width=width, height=height, skin_tone=tone,
                                background=bg, start_s=1.0, fps=1.0, hand_free_frames=0)
            preps[k] = prepare(spec)
            rends[k] = make_renderer(preps[k])
        try:
            streams = {k: render_frames(preps[k], rends[k]) for k in LOOKS}
            for _ in range(frames):
                for k in (list(LOOKS)[seed % 3:] + list(LOOKS)[: seed % 3]):  # rotate the order
                    t0 = time.perf_counter()
                    _, pair, row = next(streams[k])
                    ms[k].append(1e3 * (time.perf_counter() - t0))
                    hsv = render_tip_hsv(pair, row, preps[k].rig)
                    if len(hsv):
                        n_frames[k] += 1
                        px[k].append(hsv)
        finally:
            for r in rends.values():
                r.close()
    return {k: {"hsv": np.concatenate(px[k]) if px[k] else np.zeros((0, 3), np.uint8), "frames": n_frames[k],
                "ms": ms[k]} for k in LOOKS}


def _hue_unwrapped(h: np.ndarray) -> np.ndarray:
    """OpenCV hue (0…179) shifted so that skin's reds (≈ 170…179, 0…25) are contiguous."""
    return (h.astype(np.int32) + 90) % 180


def hsv_summary(hsv: np.ndarray, real: np.ndarray | None = None) -> dict:
    from scipy.stats import wasserstein_distance

    q = [5, 25, 50, 75, 95]
    h = hsv[:, 0].astype(int)
    out = {"pixels": int(len(hsv)),
           "percentiles": {"q": q, **{c: np.percentile(hsv[:, i], q).round(1).tolist() for i, c in enumerate("HSV")}},
           "share_s_below_40": float(np.mean(hsv[:, 1] < _S_GATE)),
           "share_v_clipped_250": float(np.mean(hsv[:, 2] >= 250)),
           "share_hue_outside_0_25_160_179": float(np.mean((h > 25) & (h < 160)))}
    if real is not None:
        d = [wasserstein_distance(_hue_unwrapped(real[:, 0]), _hue_unwrapped(hsv[:, 0])),
             wasserstein_distance(real[:, 1], hsv[:, 1]), wasserstein_distance(real[:, 2], hsv[:, 2])]
        out["wasserstein_to_real"] = {"H": float(d[0]), "S": float(d[1]), "V": float(d[2]), "sum": float(sum(d))}
    return out


def run(args: argparse.Namespace) -> dict:
    from vishap.scale.dataset_spec import _resolution

    width, height = _resolution(args.resolution)
    data = Path(args.data)
    record: dict = {"machine": machine_info(), "notes": []}
    real = None
    if (data / "images").is_dir() and (data / "labels.csv").is_file():
        real, n = real_tip_hsv(data, args.fit_last, args.every)
        record["real"] = {"data": str(data), "photos": n, "split": f"photos 1..{args.fit_last} (fit split)",
                          "pixels": f"stroke from the tip end toward the hand box centre, {_TIP_STROKE:.0%} of its diagonal",
                          **hsv_summary(real)}
    else:
        record["notes"].append(f"{data}: no images/ and labels.csv; real figures skipped")
    rendered = _renders(args.seeds, args.frames, width, height)
    record["renders"] = {"scene": "wall", "seeds": args.seeds, "frames_per_seed": args.frames,
                         "resolution": f"{width}x{height}", "camera_effects": True,
                         "pixels": "skin label inside the projected fingertip cap's disc, left view"}
    record["looks"] = {}
    for k, v in rendered.items():
        rec = hsv_summary(v["hsv"], real) if len(v["hsv"]) else {"pixels": 0}
        rec.update({"frames_with_tip": v["frames"], "ms_per_pair_median": float(np.median(v["ms"])),
                    "skin_tone": LOOKS[k][0], "background": LOOKS[k][1]})
        record["looks"][k] = rec
    record["chart"] = str(_chart(real, rendered, record, Path(args.out) / "synth_appearance_hsv.png"))
    return record


def _chart(real, rendered, record, path: Path) -> Path:
    fig, axes = new_figure(1, 4, figsize=(19, 4.6))
    bins = {"H": np.arange(0, 181, 3), "S": np.arange(0, 257, 8), "V": np.arange(0, 257, 8)}
    colours = {"plain (default)": "tab:blue", "real skin": "tab:orange", "real skin + photo": "tab:red"}
    for i, c in enumerate("HSV"):
        ax = axes[i]
        tr = (lambda x: _hue_unwrapped(x)) if c == "H" else (lambda x: x)
        if real is not None:
            ax.hist(tr(real[:, i]), bins=bins[c], density=True, color="k", alpha=0.25, label="real photos 1–600")
        for k, v in rendered.items():
            if len(v["hsv"]):
                w = record["looks"][k].get("wasserstein_to_real", {}).get(c)
                ax.hist(tr(v["hsv"][:, i]), bins=bins[c], density=True, histtype="step", lw=1.6, color=colours[k],
                        label=f"{k}" + (f" (W {w:.1f})" if w is not None else ""))
        if c == "S":
            ax.axvline(_S_GATE, color="k", ls=":", lw=1)
        ax.set_xlabel("hue + 90 (mod 180): skin reds contiguous" if c == "H" else f"{c} (OpenCV 8-bit)")
        ax.set_ylabel("density")
        ax.set_title(f"fingertip {c}")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    ax = axes[3]
    names = list(record["looks"])
    ws = [record["looks"][k].get("wasserstein_to_real", {}).get("sum", np.nan) for k in names]
    ms = [record["looks"][k]["ms_per_pair_median"] for k in names]
    for k, x, y in zip(names, ms, ws):
        ax.scatter(x, y, s=70, color=colours[k], label=k)
    ax.set_xlabel("ms per pair (median, with camera effects)")
    ax.set_ylabel("distance to real skin (W_H + W_S + W_V)")
    ax.set_title("speed vs realism of the look")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return save_figure(fig, path)
