"""``vishap tactile``: the finger-sleeve layer (PHSM worked examples, rendering contact sequences)."""
from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tactile", help="tactile sleeve: worked examples, render contact sequences to drive signals")
    ts = p.add_subparsers(dest="tactile_command", metavar="ACTION", required=True)

    ex = ts.add_parser("examples", help="classify the PHSM paper's three worked examples; print JSON")
    ex.add_argument("--config", default=None, help="tactile config file (default: built-in tactile.yaml)")
    ex.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    ex.add_argument("--noise-pa", type=float, default=None, help="sensor noise std, Pa (default: from config)")
    ex.set_defaults(func=_examples)


def _examples(args: argparse.Namespace) -> int:
    from vishap.tactile.config import load_tactile_config
    from vishap.tactile.examples import run_worked_examples

    cfg = load_tactile_config(args.config)
    print(json.dumps(run_worked_examples(cfg, seed=args.seed, noise_pa=args.noise_pa)))
    return 0
