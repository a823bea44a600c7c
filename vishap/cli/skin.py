"""``vishap skin fit DIR... --out skin.yaml``: fit the Gaussian hue skin model (VisHap §2.1) from labelled sequences;
``vishap skin fit-real IMAGES --labels CSV --out skin.npz``: fit the histogram skin model on annotated real photos."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_overwrite_flag, report


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("skin", help="fit or show the hue skin model")
    ss = p.add_subparsers(dest="skin_command", metavar="ACTION", required=True)
    f = ss.add_parser("fit", help="fit from the skin labels of synthetic sequences (use other seeds than you evaluate)")
    f.add_argument("folder", nargs="+")
    f.add_argument("--out", required=True, help="model file to write (.yaml)")
    f.add_argument("--max-sigma", type=float, default=None, help="keep hues within this many standard deviations")
    f.add_argument("--coverage", type=float, default=0.99,
                   help="without --max-sigma: threshold keeping this fraction of the training skin pixels")
    add_overwrite_flag(f, "--out file")
    add_json_flag(f)
    f.set_defaults(func=_fit)
    r = ss.add_parser("fit-real", help="fit the histogram skin model on annotated real photos (weak labels)")
    r.add_argument("images", help="folder of the photos")
    r.add_argument("--labels", required=True, help="CSV with frame,u,v and box_x0,box_y0,box_x1,box_y1")
    r.add_argument("--first", type=int, default=None, help="fit on the first N rows only (keep the rest held out)")
    r.add_argument("--threshold", type=float, default=0.5, help="P(skin | colour) above this is skin")
    r.add_argument("--out", required=True, help="model file to write (.npz)")
    add_overwrite_flag(r, "--out file")
    add_json_flag(r)
    r.set_defaults(func=_fit_real)
    s = ss.add_parser("show", help="print a model (default: the shipped one)")
    s.add_argument("file", nargs="?", default=None)
    add_json_flag(s)
    s.set_defaults(func=_show)


def _fit(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from vishap._core.output import check_output_file
    from vishap.vision.evaluate import fit_skin_model

    check_output_file(args.out, overwrite=args.overwrite)
    m = fit_skin_model(args.folder, max_sigma=args.max_sigma, coverage=args.coverage)
    m.save(args.out)
    rec = asdict(m) | {"out": args.out}
    report(args, rec, _model_lines(rec) + [f"  model file: {args.out}"])
    return 0


def _model_lines(rec: dict) -> list[str]:
    nums = {k: v for k, v in rec.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    return [f"skin model: {', '.join(f'{k} {v:.4g}' for k, v in nums.items())}"]


def _show(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from vishap.vision.skin_model import SkinModel

    rec = asdict(SkinModel.load(args.file))
    report(args, rec, _model_lines(rec))
    return 0


def _fit_real(args: argparse.Namespace) -> int:
    from vishap._core.output import check_output_file
    from vishap.vision.skin_hist import fit_skin_from_annotations, read_annotations

    check_output_file(args.out, overwrite=args.overwrite)
    rows = read_annotations(args.labels)
    frames = {r["frame"] for r in (rows if args.first is None else rows[: args.first])}
    m = fit_skin_from_annotations(args.images, args.labels, frames, threshold=args.threshold)
    m.save(args.out)
    rec = {"out": args.out, "bins": list(m.bins), "threshold": m.threshold, "source": m.source}
    report(args, rec, [f"histogram skin model ({'x'.join(map(str, m.bins))} bins, threshold {m.threshold}) "
                       f"fitted on {len(frames)} photos", f"  model file: {args.out}"])
    return 0
