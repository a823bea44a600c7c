"""``vishap bench NAME``: benchmarks that write a JSON record and charts.

Each benchmark is a module ``vishap/bench/NAME.py`` exposing ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> dict``. ``run`` writes its charts into ``args.out``;
this command prints the returned record as one JSON object and saves it as ``OUT/NAME.json``.
"""
from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
from pathlib import Path


def _bench_modules() -> dict[str, object]:
    import vishap.bench as pkg

    mods = {}
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"vishap.bench.{info.name}")
        if hasattr(mod, "run"):
            mods[info.name] = mod
    return mods


def register(sub: argparse._SubParsersAction) -> None:
    mods = _bench_modules()
    if not mods:
        return
    p = sub.add_parser("bench", help="measure speed and accuracy; write JSON and charts")
    bs = p.add_subparsers(dest="bench_name", metavar="NAME", required=True)
    for name, mod in mods.items():
        b = bs.add_parser(name, help=getattr(mod, "HELP", ""))
        b.add_argument("--out", default=None, help=f"output folder (default out/bench/{name})")
        mod.add_arguments(b)
        b.set_defaults(func=_run, bench_module=mod)


def _run(args: argparse.Namespace) -> int:
    from vishap.bench._common import to_jsonable

    if args.out is None:
        args.out = str(Path("out") / "bench" / args.bench_name)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    record = args.bench_module.run(args)
    text = json.dumps(to_jsonable(record))
    (out / f"{args.bench_name}.json").write_text(text + "\n")
    print(text)
    return 0
