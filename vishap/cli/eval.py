"""``vishap eval vision DIR``: score the vision pipeline on a labelled synthetic sequence.
``vishap eval fingertip SOURCE --labels CSV``: score a mono fingertip detector on real photos or video.

Both show a short summary (the full record with ``--json``); ``eval fingertip --out`` also writes
the record, per-frame results and overlays of the worst frames into a folder."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_overwrite_flag, add_quiet_flag, report, show_progress


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="score a subsystem on labelled sequences or photos")
    es = p.add_subparsers(dest="eval_name", metavar="NAME", required=True)
    v = es.add_parser("vision", help="segmentation ratios, tip 2-D/3-D RMS, detection rate, ms per pair")
    v.add_argument("folder", nargs="+", help="sequence folder(s) written by 'vishap synth'")
    v.add_argument("--skin", default=None, help="skin model YAML (default: the shipped model, fitted on other seeds)")
    v.add_argument("--max-frames", type=int, default=None, help="score only the first N frames of each sequence")
    v.add_argument("--full-frame", action="store_true", help="no tracking window: full-frame search every frame")
    add_quiet_flag(v)
    add_json_flag(v)
    v.set_defaults(func=_vision)
    f = es.add_parser("fingertip", help="2-D fingertip scores (PCK@10/20/30, detection, ms) of a mono detector")
    f.add_argument("source", help="folder of images, video file, LEFT,RIGHT videos or 'vishap synth' folder (left view)")
    f.add_argument("--labels", required=True, help="CSV with columns frame,u,v (u,v empty when the tip is hidden)")
    f.add_argument("--detector", default=None,
                   help="registered detector name (default: hybrid with the 'learned' extra, else geometric)")
    f.add_argument("--out", default=None,
                   help="folder for the record (fingertip.json), per-frame results (frames.csv) and overlays of the "
                        "worst frames (worst/), written whole at the end; must not exist or be empty")
    f.add_argument("--sequence", action="store_true",
                   help="treat a folder of images as consecutive frames (default: independent photos)")
    add_overwrite_flag(f)
    add_quiet_flag(f)
    add_json_flag(f)
    f.set_defaults(func=_fingertip)


def _vision(args: argparse.Namespace) -> int:
    from vishap.vision.evaluate import evaluate_sequence
    from vishap.vision.pipeline import PipelineConfig
    from vishap.vision.skin_model import SkinModel

    skin = SkinModel.load(args.skin) if args.skin else None
    cfg = PipelineConfig(tracking=not args.full_frame)
    results = [evaluate_sequence(f, skin_model=skin, config=cfg, max_frames=args.max_frames,
                                 progress=show_progress(args)) for f in args.folder]
    lines = []
    for r in results:
        lines += [f"{r['folder']}: {r['frames']} frames, fingertip detected in {_pct(r.get('detection_rate'))} of "
                  f"{r.get('visible_frames', '?')} visible",
                  f"  tip 3-D RMS {_num(r.get('tip3d_rms_mm'), ' mm')}, 2-D RMS {_num(r.get('tip2d_rms_px'), ' px')}, "
                  f"{_num(r.get('ms_per_pair'), ' ms')} per pair"]
    report(args, results[0] if len(results) == 1 else {"sequences": results}, lines)
    return 0


def _fingertip(args: argparse.Namespace) -> int:
    import sys

    from vishap.vision.detector import make_default_detector, make_detector
    from vishap.vision.fingertip_eval import evaluate_fingertip, write_fingertip_results

    if args.out is not None:  # a bad --out is refused before the photos are read
        from vishap._core.output import check_output_folder

        check_output_folder(args.out, overwrite=args.overwrite)
    if args.detector is None:
        det, note = make_default_detector()
        if note:
            print(f"vishap eval fingertip: {note}", file=sys.stderr)
    else:
        det = make_detector(args.detector)
    rec, rows = evaluate_fingertip(args.source, args.labels, det, sequence=True if args.sequence else None,
                                   progress=show_progress(args))
    lines = [f"{rec['detector']} on {args.source}: {rec['frames']} labelled frames, detection rate "
             f"{_pct(rec.get('detection_rate'))}",
             f"  PCK@10/20/30 {_pct(rec.get('pck_10'))} / {_pct(rec.get('pck_20'))} / {_pct(rec.get('pck_30'))}, "
             f"median error {_num(rec.get('median_error_px'), ' px')}, {_num(rec.get('ms_per_frame'), ' ms')} per frame"]
    if args.out is not None:
        from vishap._core.output import output_dir

        with output_dir(args.out, overwrite=args.overwrite) as o:
            write_fingertip_results(o.path, rec, rows, args.source)
        lines.append(f"  files in {o.final}: fingertip.json (the record), frames.csv, worst/")
    report(args, rec, lines)
    return 0


def _pct(x) -> str:
    return "n/a" if x is None else f"{x:.1%}"


def _num(x, unit: str) -> str:
    return "n/a" if x is None else f"{x:.2f}{unit}"
