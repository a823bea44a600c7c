"""``vishap track SOURCE --out tracks.json``: run the vision pipeline (VisHap §2.1) over a stereo source.

SOURCE is a folder written by ``vishap synth``, a pair of videos ``LEFT,RIGHT`` or ``sbs:VIDEO``
(then ``--rig`` is required). Writes per frame ``t``, ``tip_uv_left``, ``tip_uv_right``,
``tip_cam``, ``cov_cam``, ``confidence`` and timings, plus the source's frame statistics.
"""
from __future__ import annotations

import argparse
import itertools
import json
import sys

from vishap.cli import add_json_flag, add_overwrite_flag, add_quiet_flag, quiet, report


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("track", help="track the fingertip in a stereo source; write tracks.json")
    p.add_argument("source", help="synthetic folder, LEFT,RIGHT videos, sbs:VIDEO or cam:N[,M]")
    p.add_argument("--out", required=True, help="JSON file to write (every frame's track); must not exist")
    p.add_argument("--rig", default=None, help="rig file (default: SOURCE/rig.yaml for a synthetic folder)")
    p.add_argument("--skin", default=None, help="skin model YAML (default: the shipped model)")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    p.add_argument("--full-frame", action="store_true", help="search the full frame every frame (no tracking window)")
    add_overwrite_flag(p)
    add_quiet_flag(p)
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from vishap._core.config import write_atomic
    from vishap._core.output import check_output_file
    from vishap._core.results import progress
    from vishap._core.errors import VisionError
    from vishap.vision.capture import open_source
    from vishap.vision.evaluate import track_record
    from vishap.vision.pipeline import PipelineConfig, VisionPipeline
    from vishap.vision.rig import StereoRig
    from vishap.vision.skin_model import SkinModel

    out = check_output_file(args.out, overwrite=args.overwrite)  # before any frame is processed
    src = Path(args.source)
    if args.rig:
        rig = StereoRig.load(args.rig)
    elif src.is_dir() and (src / "rig.yaml").is_file():
        rig = StereoRig.load(src / "rig.yaml")
    else:
        raise VisionError(f"{args.source}: --rig is required for videos and cameras")
    source = open_source(args.source, max_frames=args.max_frames) if args.source.startswith(("cam:", "sbs-cam:")) \
        else open_source(args.source)
    frames, stats = iter(source), source.stats
    pipe = VisionPipeline(rig, skin_model=SkinModel.load(args.skin) if args.skin else None,
                          config=PipelineConfig(tracking=not args.full_frame))
    total = _length(source, args.max_frames)
    rows = []
    for f in progress(itertools.islice(frames, args.max_frames), total=total, desc="track", unit="frame",
                      quiet=quiet(args)):
        rows.append(track_record(pipe.process(f)))
    found = sum(r["found"] for r in rows)
    if pipe.background_warning:
        print(f"vishap track: warning: {pipe.background_warning}", file=sys.stderr)
    record = {"source": args.source, "frames": len(rows), "found": found,
              "background_warning": pipe.background_warning,
              "capture": None if stats is None else stats.as_dict(), "tracks": rows}
    write_atomic(out, json.dumps(record))
    report(args, {k: v for k, v in record.items() if k != "tracks"} | {"out": args.out},
           [f"tracked {len(rows)} frames of {args.source}: fingertip found in {found} "
            f"({found / max(1, len(rows)):.0%})",
            f"  every frame's track in {out}"])
    return 0


def _length(source, limit: int | None) -> int | None:
    """How many frames the run will take (for the progress bar's ETA); None when a stream cannot say."""
    try:
        n = len(source)
    except TypeError:  # cameras and streams
        return limit
    return n if limit is None else min(n, limit)
