"""``vishap dataset build SPEC.yaml --out DIR``: a mixed synthetic data set from a spec (scenes,
trajectories, seed ranges, skin tones, backgrounds, lighting, resolution, camera effects), rendered
on the scale-out engine; ``DIR/GROUP/seed-NNNNNN`` plus ``DIR/manifest.json``; a re-run resumes
(issue 18, item 2; the spec format is in :mod:`vishap.scale.dataset_spec`)."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_quiet_flag, report, show_progress


def register(sub: argparse._SubParsersAction) -> None:
    from vishap.scale.cli import add_engine_options

    p = sub.add_parser("dataset", help="build a synthetic data set from a spec file")
    ds = p.add_subparsers(dest="dataset_command", metavar="ACTION", required=True)
    b = ds.add_parser("build", help="render every sequence of SPEC.yaml under --out (resumes a stopped build)")
    b.add_argument("spec", metavar="SPEC.yaml", help="the data-set spec")
    b.add_argument("--out", required=True, help="output folder (new, empty, or an earlier build of the same spec)")
    add_quiet_flag(b)
    add_engine_options(b)
    add_json_flag(b)
    b.set_defaults(func=_build)


def _build(args: argparse.Namespace) -> int:
    from vishap.scale.cli import default_workers
    from vishap.scale.dataset_spec import load_dataset_spec
    from vishap.scale.sequences import build_sequences

    spec, jobs = load_dataset_spec(args.spec)
    summary = build_sequences(jobs, args.out, workers=default_workers(args), address=args.address, command="dataset build",
                              parameters=spec.model_dump(exclude_unset=True), progress=show_progress(args))
    rec = {"out": summary["out"], "sequences": len(jobs), "built": len(summary["built"]),
           "skipped": len(summary["skipped"]), "seconds": round(summary["seconds"], 3), "engine": summary["engine"]}
    report(args, rec, [f"data set {args.spec}: {rec['built']} sequences built, {rec['skipped']} already there, "
                       f"in {rec['seconds']:.1f} s", f"  in {rec['out']} (list and checksums: manifest.json)"])
    return 0
