"""``vishap bench vision_real``: every mono fingertip detector on real photos, beside our renders.

Real data: a folder with ``images/`` and ``labels.csv`` (``frame,u,v`` plus the TI1K extras), by
default the TI1K train split (900 photos; ``--data``, or the ``VISHAP_REAL_DATA`` environment
variable). Scores are reported on all photos used, on the *fit* split (photos 1…``--fit-last``,
the only ones looked at while the detector and the skin models were fitted and tuned) and on the
*held-out* rest. Synthetic data: the left view of ``vishap synth`` sequences (default: wall, seeds
101…106, 30 frames at 10 fps each, ramp lighting, the real skin look on a real photograph:
``--skin-tone real --background photo``; one look per seed, so several seeds span the real
photos' range of looks instead of one draw of it), pooled, labelled with the projected cap centre where the tip is
visible.

Variants: the paper's method as shipped (``paper``: with its background learned from the first
frames on the synthetic sequence), the same with the skin test alone, the improved detector
(``geometric``) and two of its skin choices (the paper's Gaussian hue model; the histogram fitted
on real skin), and every other registered detector (a learned model and a hybrid register
themselves when their extra is installed; a detector that cannot be made is listed as skipped
with the reason). The chart plots median ms per frame against PCK@20 and PCK@30, real and
synthetic, and synthetic against real PCK@30 with the rank correlation across the variants.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "real photos: speed vs PCK@20/30 of each mono fingertip detector, beside its synthetic figures"
QUICK_ARGS = ["--every", "9", "--synth-frames", "20", "--synth-seeds", "3"]

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run", "synth_labels"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", default=os.environ.get("VISHAP_REAL_DATA", "../shared/real/ti1k-train"),
                   help="real data folder with images/ and labels.csv (default: $VISHAP_REAL_DATA or "
                        "../shared/real/ti1k-train)")
    p.add_argument("--every", type=int, default=1, help="use every N-th photo (default 1: all)")
    p.add_argument("--fit-last", type=int, default=600,
                   help="photos 1..N are the fit split (tuned on), the rest held out (default 600)")
    p.add_argument("--synth", default=None,
                   help="'vishap synth' folder(s), comma-separated (default: render wall, seeds 101.., real look)")
    p.add_argument("--synth-frames", type=int, default=30, help="frames of each default synthetic sequence (10 fps)")
    p.add_argument("--synth-seeds", type=int, default=6, help="default synthetic sequences: seeds 101 .. 101+N-1")
    p.add_argument("--detectors", default=None, help="comma-separated registered names to add (default: all)")


def _variants(extra: str | None) -> dict:
    from vishap.vision.detector import detector_names, make_detector
    from vishap.vision.mono import PAPER, GeometricConfig, GeometricDetector

    out = {
        "paper (as shipped)": lambda: make_detector("paper"),
        "paper, skin only": lambda: GeometricDetector(replace(PAPER, background="none"), name="paper-skin-only"),
        "geometric (improved)": lambda: make_detector("geometric"),
        "geometric, Gaussian hue skin": lambda: GeometricDetector(replace(GeometricConfig(), skin="gaussian"),
                                                                  name="geometric-gaussian"),
        "geometric, real-skin histogram": lambda: GeometricDetector(replace(GeometricConfig(), skin="real"),
                                                                    name="geometric-histogram"),
    }
    names = [n for n in detector_names() if n not in ("paper", "geometric")]
    if extra:
        names = [n.strip() for n in extra.split(",") if n.strip()]
    for n in names:
        out[n] = lambda n=n: make_detector(n)
    if "learned" in names:  # the "before" of the hand recovery, in the same run
        out["learned, MediaPipe's palm rule"] = _learned_mediapipe_rule
    return out


def _learned_mediapipe_rule():
    from vishap._core.errors import ConfigError
    from vishap.vision import learned as L

    if not L.runtime_available():
        raise ConfigError(L.INSTALL_HINT)
    return L.LearnedDetector(L.LearnedConfig(**L.MEDIAPIPE_PALM_RULE))


def synth_labels(folder: Path, out_csv: Path, frames: int | None = None) -> Path:
    """``frame,u,v`` of a ``vishap synth`` folder's left view: the projected cap centre where the
    tip is visible, empty otherwise."""
    with np.load(folder / "gt.npz", allow_pickle=False) as gt:
        uv, vis = gt["tip_uv_left"], gt["tip_visible_left"].astype(bool)
    n = len(uv) if frames is None else min(frames, len(uv))
    lines = ["frame,u,v"] + [f"{i},{uv[i, 0]:.3f},{uv[i, 1]:.3f}" if vis[i] else f"{i},," for i in range(n)]
    out_csv.write_text("\n".join(lines) + "\n")
    return out_csv


def _render(tmp: Path, frames: int, seeds: int) -> list[Path] | None:
    from vishap.cli import main as cli

    out = []
    for seed in range(101, 101 + seeds):
        # the real look (skin and a photograph as measured on real photos, docs/synth.md): the plain
        # look's render could not tell the variants apart
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # keep `--json` output to the bench's record
                ok = cli(["synth", "--scene", "wall", "--frames", str(frames), "--seed", str(seed),
                          "--lighting", "ramp", "--fps", "10", "--hand-free", "3", "--skin-tone", "real",
                          "--background", "photo", "--out", str(tmp / f"wall_{seed}"), "--quiet"]) == 0
        except Exception:  # no renderer here (EGL missing)
            ok = False
        if not ok:
            return None
        out.append(tmp / f"wall_{seed}")
    return out


def _split(frame: str, fit_last: int) -> str:
    import re

    runs = re.findall(r"\d+", Path(frame).stem)  # the frame number: the last run of digits
    digits = runs[-1] if runs else ""
    return "fit" if digits and int(digits) <= fit_last else "held_out"


def run(args: argparse.Namespace) -> dict:
    from vishap.vision.fingertip_eval import evaluate_fingertip, read_fingertip_labels, score_fingertips

    out_dir = Path(args.out)
    data = Path(args.data)
    record: dict = {"machine": machine_info(), "variants": {}, "notes": []}
    real_ok = (data / "images").is_dir() and (data / "labels.csv").is_file()
    if real_ok:
        labels = read_fingertip_labels(data / "labels.csv")
        subset = {x.frame for x in labels[:: max(1, args.every)]}
        record["real"] = {"data": str(data), "photos": len(subset), "every": args.every,
                          "fit_split": f"photos 1..{args.fit_last} (fitted and tuned on)",
                          "held_out_split": f"photos {args.fit_last + 1}.. (never looked at while tuning)"}
    else:
        record["notes"].append(f"{data}: no images/ and labels.csv; real figures skipped")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        synth = ([Path(f) for f in args.synth.split(",")] if args.synth
                 else _render(tmp, args.synth_frames, args.synth_seeds))
        if synth is None:
            record["notes"].append("no renderer: synthetic figures skipped")
        else:
            synth = [(f, synth_labels(f, tmp / f"synth_labels_{i}.csv")) for i, f in enumerate(synth)]
            record["synthetic"] = {"sequences": [f.name for f, _ in synth], "view": "left"}
        from vishap._core.results import progress

        for name, make in progress(list(_variants(args.detectors).items()), desc="bench vision_real", unit="variant",
                                   quiet=getattr(args, "quiet", False)):
            rec: dict = {}
            try:
                det = make()
            except Exception as exc:  # an optional detector without its extra: say why
                record["variants"][name] = {"skipped": str(exc)}
                continue
            if real_ok:
                r, rows = evaluate_fingertip(data / "images", data / "labels.csv", det, subset=subset)
                rec["real"] = _short(r)
                for split in ("fit", "held_out"):
                    part = [x for x in rows if _split(x["frame"], args.fit_last) == split and x["u_gt"] is not None]
                    if part:
                        s = score_fingertips([x["error_px"] if x["found"] else None for x in part])
                        s["ms_per_frame"] = float(np.median([x["ms"] for x in part]))
                        rec[f"real_{split}"] = _short(s)
            if synth is not None:
                rows = [x for f, csv in synth for x in evaluate_fingertip(f, csv, det)[1]]
                vis = [x for x in rows if x["u_gt"] is not None]
                r = score_fingertips([x["error_px"] if x["found"] else None for x in vis],
                                     [x["found"] for x in rows if x["u_gt"] is None])
                r["ms_per_frame"] = float(np.median([x["ms"] for x in rows]))
                rec["synthetic"] = _short(r)
            rec["detector"] = getattr(det, "name", name)
            record["variants"][name] = rec
    record["synthetic_predicts_real"] = _prediction(record["variants"])
    record["chart"] = str(_chart(record, out_dir / "vision_real_speed_accuracy.png"))
    return record


def _short(r: dict) -> dict:
    keys = ("frames", "detection_rate", "pck_10", "pck_20", "pck_30", "median_error_px", "ms_per_frame",
            "hidden_frames", "false_detections")
    return {k: r[k] for k in keys if k in r}


def _prediction(variants: dict) -> dict:
    """Do synthetic PCK@30 scores rank the variants as the real ones do? (Spearman's rho.)"""
    pairs = [(v["synthetic"]["pck_30"], v["real"]["pck_30"]) for v in variants.values()
             if "synthetic" in v and "real" in v]
    if len(pairs) < 3:
        return {"variants": len(pairs), "spearman_rho": None, "note": "fewer than 3 variants with both figures"}
    from scipy.stats import spearmanr

    s, r = np.array(pairs).T
    if np.ptp(s) == 0 or np.ptp(r) == 0:
        return {"variants": len(pairs), "spearman_rho": None, "max_abs_gap_pck_30": float(np.max(np.abs(s - r))),
                "note": "all variants score the same on one of the two: no ranking to compare"}
    rho = spearmanr(s, r).statistic
    # the spread says whether a ranking exists at all: on a render every variant may score alike
    return {"variants": len(pairs), "spearman_rho": None if not np.isfinite(rho) else float(rho),
            "max_abs_gap_pck_30": float(np.max(np.abs(s - r))),
            "spread_pck_30": {"synthetic": float(np.ptp(s)), "real": float(np.ptp(r))}}


def _chart(record: dict, path: Path) -> Path:
    fig, axes = new_figure(1, 3, figsize=(17, 5.2))
    cmap = __import__("matplotlib").colormaps["tab10"]
    items = [(k, v) for k, v in record["variants"].items() if "skipped" not in v]
    for i, (name, v) in enumerate(items):
        col = cmap(i % 10)
        for ax, key in ((axes[0], "pck_20"), (axes[1], "pck_30")):
            for src, mk, fill in (("real", "o", True), ("real_held_out", "D", True), ("synthetic", "s", False)):
                if src in v:
                    ax.scatter(max(v[src]["ms_per_frame"] or 1e-3, 1e-3), v[src][key], marker=mk, s=60,
                               facecolors=col if fill else "none", edgecolors=col,
                               label=f"{name}" if (src == "real" and key == "pck_20") else None)
        if "real" in v and "synthetic" in v:
            axes[2].scatter(v["synthetic"]["pck_30"], v["real"]["pck_30"], color=col, s=60)
            axes[2].annotate(name, (v["synthetic"]["pck_30"], v["real"]["pck_30"]), fontsize=7)
    for ax, key in ((axes[0], "PCK@20"), (axes[1], "PCK@30")):
        ax.set_xscale("log")
        ax.set_xlabel("ms per frame (median)")
        ax.set_ylabel(key)
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
    axes[0].set_title("o real (all)  ◆ real held-out  □ synthetic")
    axes[0].legend(fontsize=7, loc="best")
    pr = record.get("synthetic_predicts_real", {})
    axes[2].plot([0, 1], [0, 1], "k:", lw=0.8)
    axes[2].set_xlabel("synthetic PCK@30")
    axes[2].set_ylabel("real PCK@30")
    rho = pr.get("spearman_rho")
    spread = pr.get("spread_pck_30", {})
    axes[2].set_title(f"synthetic vs real: Spearman rho {'n/a' if rho is None else f'{rho:.2f}'}, "
                      f"spread {spread.get('synthetic', float('nan')):.2f} vs {spread.get('real', float('nan')):.2f}", fontsize=9)
    axes[2].set_xlim(-0.02, 1.02)
    axes[2].set_ylim(-0.02, 1.02)
    axes[2].grid(alpha=0.3)
    return save_figure(fig, path)
