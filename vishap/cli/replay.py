"""``vishap replay LOG``: re-run vision, world and tactile from a demo's log (issue 9 part 4)."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_overwrite_flag, add_quiet_flag, report, show_progress

__all__ = ["register"]

#: what ``--out`` receives (:func:`vishap.apps.replay.replay`)
OUT_FILES = ("replay_log.npz", "replay.json")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="re-run vision/world/tactile from a demo log and compare with it")
    p.add_argument("log", help="a demo's log.npz (or its output folder)")
    p.add_argument("--out", default=None,
                   help=f"folder for the replayed log ({OUT_FILES[0]}) and the comparison ({OUT_FILES[1]}), "
                        "written whole at the end; must not exist or be empty")
    p.add_argument("--atol", type=float, default=0.0, help="tolerance for 'identical' (default 0: bit-exact)")
    add_overwrite_flag(p)
    add_quiet_flag(p)
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from vishap._core.output import output_dir
    from vishap.apps.replay import replay, summary_lines

    if args.out is None:
        rec = replay(args.log, atol=args.atol, progress=show_progress(args))
        report(args, rec, summary_lines(rec, args.atol))
    else:
        with output_dir(args.out, overwrite=args.overwrite) as o:
            rec = replay(args.log, out=o.path, atol=args.atol, progress=show_progress(args))
        report(args, rec, summary_lines(rec, args.atol) + [f"  files in {o.final}: {', '.join(OUT_FILES)}"])
    return 0 if rec["identical"] else 1
