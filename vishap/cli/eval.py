"""``vishap eval vision DIR``: score the vision pipeline on a labelled synthetic sequence (one JSON object)."""
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


def _vision(args: argparse.Namespace) -> int:
    from vishap.vision.evaluate import evaluate_sequence
    from vishap.vision.pipeline import PipelineConfig
    from vishap.vision.skin_model import SkinModel

    skin = SkinModel.load(args.skin) if args.skin else None
    cfg = PipelineConfig(tracking=not args.full_frame)
    results = [evaluate_sequence(f, skin_model=skin, config=cfg, max_frames=args.max_frames) for f in args.folder]
    print(json.dumps(results[0] if len(results) == 1 else {"sequences": results}))
    return 0
