"""``vishap dataset build SPEC.yaml --out DIR``: a mixed synthetic data set from a spec (scenes,
trajectories, seed ranges, skin tones, backgrounds, lighting, resolution, camera effects), rendered
on the scale-out engine; ``DIR/GROUP/seed-NNNNNN`` plus ``DIR/manifest.json``; a re-run resumes
(issue 18, item 2; the spec format is in :mod:`vishap.scale.dataset_spec`)."""
from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    from vishap.scale.cli import add_engine_options

    p = sub.add_parser("dataset", help="build a synthetic data set from a spec file")
    ds = p.add_subparsers(dest="dataset_command", metavar="ACTION", required=True)
    b = ds.add_parser("build", help="render every sequence of SPEC.yaml under --out (resumes a stopped build)")
    b.add_argument("spec", metavar="SPEC.yaml", help="the data-set spec")
    b.add_argument("--out", required=True, help="output folder (new, empty, or an earlier build of the same spec)")
    b.add_argument("--quiet", action="store_true", help="no progress bar")
    add_engine_options(b)
    b.set_defaults(func=_build)


def _build(args: argparse.Namespace) -> int:
    from vishap.scale.cli import default_workers
    from vishap.scale.dataset_spec import load_dataset_spec
    from vishap.scale.sequences import build_sequences

    spec, jobs = load_dataset_spec(args.spec)
    summary = build_sequences(jobs, args.out, workers=default_workers(args), address=args.address, command="dataset build",
                              parameters=spec.model_dump(exclude_unset=True), progress=not args.quiet)
    print(json.dumps({"out": summary["out"], "sequences": len(jobs), "built": len(summary["built"]),
                      "skipped": len(summary["skipped"]), "seconds": round(summary["seconds"], 3),
                      "engine": summary["engine"]}))
    return 0
