"""``vishap replay LOG``: re-run vision, world and tactile from a demo's log (issue 9 part 4)."""
from __future__ import annotations

import argparse
import json

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="re-run vision/world/tactile from a demo log and compare with it")
    p.add_argument("log", help="a demo's log.npz (or its output folder)")
    p.add_argument("--out", default=None, help="write the replayed log.npz and summary.json here")
    p.add_argument("--atol", type=float, default=0.0, help="tolerance for 'identical' (default 0: bit-exact)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from vishap.apps.replay import replay

    report = replay(args.log, out=args.out, atol=args.atol)
    print(json.dumps(report))
    return 0 if report["identical"] else 1
