"""Command-line pieces shared by ``vishap synth --seeds`` and ``vishap dataset build``: the engine
options and the seed range."""
from __future__ import annotations

import argparse
import dataclasses
import os

from vishap._core.errors import ConfigError

__all__ = ["add_engine_options", "seed_range", "default_workers", "engine_args", "run_seeds"]


def seed_range(text: str) -> range:
    """``A:B`` → seeds A … B−1 (a Python range; ``0:100`` is 100 seeds)."""
    a, sep, b = str(text).partition(":")
    try:
        if not sep:
            raise ValueError
        r = range(int(a), int(b))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected A:B (seeds A … B-1), got {text!r}") from None
    if r.start < 0 or len(r) == 0:
        raise argparse.ArgumentTypeError(f"expected 0 <= A < B, got {text!r}")
    return r


def add_engine_options(p: argparse.ArgumentParser, *, sweep: bool = False) -> None:
    """``--workers N`` and ``--address ADDR``. A sequence build (``sweep=False``) uses this machine's
    cores by default; a benchmark sweep (``sweep=True``) runs in its own process unless asked,
    so that a plain ``vishap bench NAME`` starts no Ray."""
    here = "1: in this process" if sweep else "this machine's cores"
    p.add_argument("--workers", type=int, default=None,
                   help=f"tasks (sequences, cases) run at once as Ray tasks (default {here}; with --address, the "
                        "cluster's CPUs); 1 runs them in this process without Ray")
    p.add_argument("--address", default=None,
                   help="an existing Ray cluster (HOST:PORT, ray://HOST:PORT or auto); unreachable: an error, never a local run")
    p.set_defaults(engine_sweep=sweep)


def default_workers(args: argparse.Namespace) -> int | None:
    """The worker count ``--workers``/``--address`` ask for (None: as many as the cluster has CPUs)."""
    if args.workers is not None:
        return args.workers
    if args.address is not None:
        return None
    return 1 if getattr(args, "engine_sweep", False) else (os.cpu_count() or 1)


def engine_args(args: argparse.Namespace) -> dict:
    """``workers=…, address=…, progress=…`` for :func:`~vishap.scale.map_cases` from parsed options; options
    built without the engine's (a caller's own namespace) run in this process."""
    from vishap._core.results import progress_shown

    shown = progress_shown(getattr(args, "quiet", False))
    if not hasattr(args, "workers"):
        return {"workers": 1, "address": None, "progress": shown}
    return {"workers": default_workers(args), "address": args.address, "progress": shown}


def run_seeds(args: argparse.Namespace, spec) -> int:
    """``vishap synth --seeds A:B [--workers N] [--address ADDR]``: one sequence per seed."""
    from vishap.cli import report, show_progress
    from vishap.scale.manifest import sha256
    from vishap.scale.sequences import Job, build_sequences, seed_folder, spec_parameters

    if args.seeds is None:
        raise ConfigError("--workers and --address render several seeds: give --seeds A:B", field="seeds")
    if args.overwrite:
        raise ConfigError("--overwrite does not apply to --seeds: a re-run keeps finished sequences and redoes the rest",
                          field="overwrite")
    rig_sha = None
    if args.rig:
        with open(args.rig, "rb") as f:
            rig_sha = sha256(f.read())
    jobs = []
    for s in args.seeds:
        one = dataclasses.replace(spec, seed=s)
        jobs.append(Job(seed_folder(s), one, spec_parameters(one, rig_sha256=rig_sha)))
    common = spec_parameters(spec, rig_sha256=rig_sha)
    common.pop("seed")
    common["seeds"] = [args.seeds.start, args.seeds.stop]
    summary = build_sequences(jobs, args.out, workers=default_workers(args), address=args.address,
                              command="synth", parameters=common, progress=show_progress(args))
    rec = {"out": summary["out"], "built": len(summary["built"]), "skipped": len(summary["skipped"]),
           "seconds": round(summary["seconds"], 3), "engine": summary["engine"]}
    report(args, rec, [f"synth seeds {args.seeds.start}:{args.seeds.stop}: {rec['built']} built, {rec['skipped']} "
                       f"already there, in {rec['seconds']:.1f} s",
                       f"  in {rec['out']} (one seed-NNNNNN folder each; checksums: manifest.json)"])
    return 0
