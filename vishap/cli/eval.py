"""``vishap eval vision DIR``: score the vision pipeline on a labelled synthetic sequence (one JSON object).
``vishap eval fingertip SOURCE --labels CSV``: score a mono fingertip detector on real photos or video."""
from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="score a subsystem on labelled synthetic sequences (JSON)")
    es = p.add_subparsers(dest="eval_name", metavar="NAME", required=True)
    v = es.add_parser("vision", help="segmentation ratios, tip 2-D/3-D RMS, detection rate, ms per pair")
    v.add_argument("folder", nargs="+", help="sequence folder(s) written by 'vishap synth'")
    v.add_argument("--skin", default=None, help="skin model YAML (default: the shipped model, fitted on other seeds)")
    v.add_argument("--max-frames", type=int, default=None)
    v.add_argument("--full-frame", action="store_true", help="no tracking window: full-frame search every frame")
    v.set_defaults(func=_vision)
    f = es.add_parser("fingertip", help="2-D fingertip scores (PCK@10/20/30, detection, ms) of a mono detector")
    f.add_argument("source", help="folder of images, video file, LEFT,RIGHT videos or 'vishap synth' folder (left view)")
    f.add_argument("--labels", required=True, help="CSV with columns frame,u,v (u,v empty when the tip is hidden)")
    f.add_argument("--detector", default=None,
                   help="registered detector name (default: hybrid with the 'learned' extra, else geometric)")
    f.add_argument("--out", default=None, help="folder for per-frame results (frames.csv) and overlays of the worst frames")
    f.add_argument("--sequence", action="store_true",
                   help="treat a folder of images as consecutive frames (default: independent photos)")
    f.set_defaults(func=_fingertip)


def _vision(args: argparse.Namespace) -> int:
    from vishap.vision.evaluate import evaluate_sequence
    from vishap.vision.pipeline import PipelineConfig
    from vishap.vision.skin_model import SkinModel

    skin = SkinModel.load(args.skin) if args.skin else None
    cfg = PipelineConfig(tracking=not args.full_frame)
    results = [evaluate_sequence(f, skin_model=skin, config=cfg, max_frames=args.max_frames) for f in args.folder]
    print(json.dumps(results[0] if len(results) == 1 else {"sequences": results}))
    return 0


def _fingertip(args: argparse.Namespace) -> int:
    import sys

    from vishap.vision.detector import make_default_detector, make_detector
    from vishap.vision.fingertip_eval import evaluate_fingertip, write_fingertip_results

    if args.detector is None:
        det, note = make_default_detector()
        if note:
            print(f"vishap eval fingertip: {note}", file=sys.stderr)
    else:
        det = make_detector(args.detector)
    rec, rows = evaluate_fingertip(args.source, args.labels, det, sequence=True if args.sequence else None)
    if args.out:
        write_fingertip_results(args.out, rec, rows, args.source)
    print(json.dumps(rec))
    return 0
