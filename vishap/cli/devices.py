"""``vishap devices``: the registered haptic-device drivers and, where they open here, their limits."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, report


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("devices", help="list the haptic-device drivers (entry points 'vishap.devices') and their limits")
    p.add_argument("--no-open", action="store_true", help="only list names and targets; open no device")
    add_json_flag(p)
    p.set_defaults(func=_devices)


def _devices(args: argparse.Namespace) -> int:
    from vishap.robot.drivers import describe_all, registered

    rows = {n: {"target": t} for n, t in registered().items()} if args.no_open else describe_all()
    lines = []
    for name, row in rows.items():
        detail = ", ".join(f"{k} {v}" for k, v in row.items() if k != "target" and isinstance(v, (int, float, str)))
        lines.append(f"{name}: {row.get('target', '')}" + (f" ({detail})" if detail else ""))
    report(args, rows, lines or ["no device drivers registered"])
    return 0
