"""``vishap tactile``: the finger-sleeve layer (PHSM worked examples, rendering contact sequences)."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_overwrite_flag, report


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tactile", help="tactile sleeve: worked examples, render contact sequences to drive signals")
    ts = p.add_subparsers(dest="tactile_command", metavar="ACTION", required=True)

    ex = ts.add_parser("examples", help="classify the PHSM paper's three worked examples; print JSON")
    ex.add_argument("--config", default=None, help="tactile config file (default: built-in tactile.yaml)")
    ex.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    ex.add_argument("--noise-pa", type=float, default=None, help="sensor noise std, Pa (default: from config)")
    add_json_flag(ex)
    ex.set_defaults(func=_examples)

    rd = ts.add_parser("render", help="render a contact sequence to drive signals (NPZ, WAV) and plots")
    src = rd.add_mutually_exclusive_group()
    src.add_argument("--scenario", default="stroke", choices=["stroke", "press", "approach", "slip"],
                     help="built-in synthetic contact sequence (default stroke)")
    src.add_argument("--input", default=None,
                     help="NPZ of contact samples: t, position (N,3), normal_force_n, velocity (N,3), in_contact")
    rd.add_argument("--surface", default="fabric", help="surface name from the config (default fabric)")
    rd.add_argument("--config", default=None, help="tactile config file (default: built-in tactile.yaml)")
    rd.add_argument("--out", default="out/tactile",
                    help="output folder, written whole at the end; must not exist or be empty (default out/tactile)")
    rd.add_argument("--no-feedforward", action="store_true", help="reactive rendering only")
    rd.add_argument("--pitch-deg", type=float, default=None,
                    help="finger pitch to the surface, degrees (e.g. 10: flat pad stroke, 70: fingertip)")
    rd.add_argument("--no-plots", action="store_true", help="skip the PNG charts")
    rd.add_argument("--seed", type=int, default=0, help="seed of the textile tile / non-uniformity map")
    add_overwrite_flag(rd)
    add_json_flag(rd)
    rd.set_defaults(func=_render)


def _examples(args: argparse.Namespace) -> int:
    from vishap.tactile.config import load_tactile_config
    from vishap.tactile.examples import run_worked_examples

    cfg = load_tactile_config(args.config)
    rec = run_worked_examples(cfg, seed=args.seed, noise_pa=args.noise_pa)
    lines = [f"PHSM worked examples: {'all classified correctly' if rec.get('all_correct') else 'NOT all correct'}"]
    for name, ex in rec.items():
        if isinstance(ex, dict) and "state" in ex:
            lines.append(f"  {name}: {ex['state']}")
    report(args, rec, lines)
    return 0


def _render(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    import numpy as np

    from vishap._core.config import reading, write_atomic
    from vishap._core.errors import ConfigError
    from vishap._core.output import output_dir
    from vishap.tactile.config import load_tactile_config
    from vishap.tactile.renderer import TactileRenderer
    from vishap.tactile.scenarios import SCENARIOS, from_arrays

    cfg = load_tactile_config(args.config)
    if args.surface not in cfg.surfaces:
        raise ConfigError(f"unknown surface {args.surface!r}; expected one of {sorted(cfg.surfaces)}", field="surfaces")
    if args.input:
        path = Path(args.input)
        if not path.is_file():
            raise ConfigError("file not found", file=path)
        with reading(path), np.load(path, allow_pickle=False) as d:
            missing = {"t", "position", "normal_force_n", "velocity", "in_contact"} - set(d.files)
            if missing:
                raise ConfigError(f"missing arrays {sorted(missing)}", file=path)
            arrays = {k: d[k] for k in d.files}
            for k, a in arrays.items():
                if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
                    raise ConfigError("contains NaN or inf", file=path, field=k)
            samples = from_arrays(arrays)
    else:
        samples = SCENARIOS[args.scenario]()
    if args.pitch_deg is not None:
        import dataclasses
        import math

        p = math.radians(args.pitch_deg)
        d = np.array([math.cos(p), 0.0, -math.sin(p)])
        samples = [dataclasses.replace(s, finger_dir=d) for s in samples]
    r = TactileRenderer(cfg, surface=args.surface, seed=args.seed, feedforward=not args.no_feedforward)
    with output_dir(args.out, overwrite=args.overwrite) as folder:
        out = r.render(samples)
        rec = {"out": str(folder.final), **_write_render(folder.path, out, samples, args)}
        rec["files"].append("render.json")
        write_atomic(folder.path / "render.json", json.dumps(rec) + "\n")
    report(args, rec, [f"rendered {rec['duration_s']} s of {args.input or args.scenario} on {args.surface} "
                       f"({rec['ticks']} ticks, states {rec['state_ticks']}) to {folder.final}",
                       f"  files: {', '.join(rec['files'])}"])
    return 0


def _write_render(od, out, samples, args) -> dict:
    """Write the drive signals (NPZ, WAV) and charts of one render into ``od``; returns the record."""
    import numpy as np
    from scipy.io import wavfile

    from vishap.tactile.plots import plot_drive, plot_spectrogram, sleeve_mix

    trace = out.extra["trace"]
    tick_t = np.array([d["t"] for d in trace])
    states = [d["state"] for d in trace]
    np.savez_compressed(od / "drive.npz", fs=out.fs, t0=out.t0, glove=out.glove.astype(np.float32),
                        regions=out.regions.astype(np.float32), pins=out.pins.astype(np.float32), tick_t=tick_t,
                        state=np.array(states), envelope=out.envelope, prearmed=out.prearmed)
    fs = int(round(out.fs))
    channels = np.vstack([out.glove[None], out.regions, out.pins.mean(axis=0)[None]]).T.astype(np.float32)
    wavfile.write(od / "drive.wav", fs, channels)
    mix = sleeve_mix(out.regions, out.pins)
    mix = (mix / max(np.abs(mix).max(), 1e-9) * 0.9).astype(np.float32)
    wavfile.write(od / "sleeve_mix.wav", fs, mix)
    files = ["drive.npz", "drive.wav", "sleeve_mix.wav"]
    if not args.no_plots:
        plot_drive(od / "drive.png", out.fs, out.glove, out.regions, out.pins, tick_t, states,
                   title=f"{args.input or args.scenario} on {args.surface}")
        speed = [s.tangential_speed for s in samples]
        plot_spectrogram(od / "spectrogram.png", out.fs, mix, tick_t, speed, title=f"sleeve mix: {args.input or args.scenario}")
        files += ["drive.png", "spectrogram.png"]
    counts = {s: states.count(s) for s in sorted(set(states))}
    return {"files": files, "fs_hz": out.fs, "samples": int(out.n), "ticks": len(trace),
            "duration_s": round(out.n / out.fs, 4), "state_ticks": counts,
            "channels": {"glove": 1, "regions": 3, "pins": int(out.pins.shape[0])},
            "wav_channels": ["glove", "R1", "R2", "R3", "pins_mean"]}
