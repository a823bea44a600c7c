"""``vishap skin fit DIR... --out skin.yaml``: fit the Gaussian hue skin model (VisHap §2.1) from labelled sequences."""
from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("skin", help="fit or show the hue skin model")
    ss = p.add_subparsers(dest="skin_command", metavar="ACTION", required=True)
    f = ss.add_parser("fit", help="fit from the skin labels of synthetic sequences (use other seeds than you evaluate)")
    f.add_argument("folder", nargs="+")
    f.add_argument("--out", required=True, help="model file to write (.yaml)")
    f.add_argument("--max-sigma", type=float, default=None, help="keep hues within this many standard deviations")
    f.add_argument("--coverage", type=float, default=0.99,
                   help="without --max-sigma: threshold keeping this fraction of the training skin pixels")
    f.set_defaults(func=_fit)
    s = ss.add_parser("show", help="print a model (default: the shipped one)")
    s.add_argument("file", nargs="?", default=None)
    s.set_defaults(func=_show)


def _fit(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from vishap.vision.evaluate import fit_skin_model

    m = fit_skin_model(args.folder, max_sigma=args.max_sigma, coverage=args.coverage)
    m.save(args.out)
    print(json.dumps(asdict(m) | {"out": args.out}))
    return 0


def _show(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from vishap.vision.skin_model import SkinModel

    print(json.dumps(asdict(SkinModel.load(args.file))))
    return 0
