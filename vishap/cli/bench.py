"""``vishap bench NAME``: benchmarks that write a JSON record and charts.

Each benchmark is a module ``vishap/bench/NAME.py`` exposing ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> dict`` (and optionally ``summary_lines(record)`` for
the terminal). ``run`` writes its charts into ``args.out``, which is a temporary folder renamed to
``--out`` when the benchmark has finished (:func:`vishap._core.output.output_dir`); this command
saves the record as ``OUT/NAME.json`` and prints a summary (the record itself with ``--json``).
While it runs, a benchmark shows its progress over cases or sweeps with
:func:`vishap._core.results.progress` (``quiet=args.quiet``).
"""
from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
from pathlib import Path

from vishap._core.results import summary_lines
from vishap.cli import add_json_flag, add_overwrite_flag, add_quiet_flag, report


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
        b.add_argument("--out", default=None,
                       help=f"output folder, written whole at the end; must not exist or be empty "
                            f"(default out/bench/{name})")
        add_overwrite_flag(b)
        add_json_flag(b)
        add_quiet_flag(b)
        mod.add_arguments(b)
        b.set_defaults(func=_run, bench_module=mod)


def _run(args: argparse.Namespace) -> int:
    from vishap._core.config import write_atomic
    from vishap._core.output import output_dir
    from vishap.bench._common import to_jsonable

    final = Path(args.out if args.out is not None else Path("out") / "bench" / args.bench_name)
    with output_dir(final, overwrite=args.overwrite) as folder:
        args.out = str(folder.path)
        record = to_jsonable(args.bench_module.run(args))
        # the record names files where they will be, not in the temporary folder
        record = json.loads(folder.relocate(json.dumps(record)))
        write_atomic(folder.path / f"{args.bench_name}.json", json.dumps(record) + "\n")
    args.out = str(folder.final)
    lines_of = getattr(args.bench_module, "summary_lines", None)
    lines = [f"bench {args.bench_name}: record in {folder.final / (args.bench_name + '.json')}"]
    lines += lines_of(record) if lines_of is not None else summary_lines(record)
    report(args, record, lines)
    return 0
