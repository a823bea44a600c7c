"""``vishap synth --scene {wall,button,fabric} --frames N --seed S --out DIR``: render a synthetic stereo
sequence with exact ground truth (issue 3; layout in :mod:`vishap.sim.writer`)."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_quiet_flag, report, show_progress


def _resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    return w, h


def _tone(text: str):
    try:
        return float(text)
    except ValueError:
        return text


def register(sub: argparse._SubParsersAction) -> None:
    from vishap.sim.scene_objects import SCENE_NAMES
    from vishap.sim.sequence import LIGHTING

    p = sub.add_parser("synth", help="render a synthetic stereo sequence with ground truth")
    p.add_argument("--scene", required=True, help=f"scene name ({', '.join(SCENE_NAMES)}) or a scene .yaml file")
    p.add_argument("--frames", type=int, required=True, help="number of frames (> 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice (same seed, same bytes)")
    p.add_argument("--out", required=True, help="output folder (must not exist or be empty)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("--resolution", type=_resolution, default=(640, 480), metavar="WxH", help="image size (default 640x480)")
    p.add_argument("--rig", default=None, help="a rig file (OpenCV FileStorage) instead of the default 60° / 60 mm rig")
    p.add_argument("--trajectory", default=None, help="trajectory name or .yaml file (default: the scene's)")
    p.add_argument("--fps", type=float, default=None, help="frame rate (default: the trajectory's, 30 Hz)")
    p.add_argument("--hand-free", type=int, default=None, help="frames without the hand at the start (default 10)")
    p.add_argument("--start", type=float, default=0.0, metavar="SECONDS",
                   help="script time of the first frame (default 0; later starts skip the hand-free frames)")
    p.add_argument("--lighting", choices=LIGHTING, default="constant", help="light change during the sequence")
    p.add_argument("--skin-tone", type=_tone, default=None,
                   help="light, medium, tan, dark or a number 0 (light) … 1 (dark); default: chosen by seed; "
                        "real or real:TONE: skin and light as measured on real photos (pale highlights, shading)")
    p.add_argument("--background", default="auto",
                   help="table texture: auto (ordinary, by seed), mixed (skin-like hard negative for 1 seed in 5), "
                        "or a name: grey, concrete, checker, blue_cloth, cutting_mat, wood*, beige* (*skin-like); "
                        "photo, photo:NAME or photo:FILE: a real photograph (shipped ones: hopper)")
    p.add_argument("--no-occlusion", dest="occlusion", action="store_false", help="no rod crossing the view")
    p.add_argument("--no-effects", dest="effects", action="store_false",
                   help="exact pixels: no sensor noise, defocus, motion blur or auto-exposure")
    p.add_argument("--msaa", type=int, default=0, help="anti-aliasing samples (0, 2, 4, 8; labels then cost a pass)")
    p.add_argument("--exposure-ms", type=float, default=None, metavar="MS",
                   help="the cameras' exposure time (default 12 ms): motion blur shortens with it, sensor noise "
                        "grows as the gain makes up the level under the same light")
    add_quiet_flag(p)
    p.add_argument("--store", choices=("png", "video"), default="png",
                   help="png: one file per image (default); video: each image stream as a lossless FFV1 video "
                        "(smaller; read by 'vishap track' and 'vishap eval' like the PNGs)")
    _add_scale_options(p)
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from vishap.sim.sequence import SequenceSpec
    from vishap.sim.writer import write_sequence
    from vishap.vision.rig import StereoRig

    rig = StereoRig.load(args.rig) if args.rig else None
    spec = SequenceSpec(scene=args.scene, frames=args.frames, seed=args.seed, trajectory=args.trajectory,
                        width=args.resolution[0], height=args.resolution[1], rig=rig, lighting=args.lighting,
                        skin_tone=args.skin_tone, background=args.background, occlusion=args.occlusion,
                        effects=args.effects, msaa=args.msaa, fps=args.fps,
                        exposure_s=None if args.exposure_ms is None else args.exposure_ms / 1e3, hand_free_frames=args.hand_free,
                        start_s=args.start, store=args.store)
    _check_render_args(spec)
    if args.seeds is not None or args.workers is not None or args.address is not None:
        return _run_seeds(args, spec)
    out = write_sequence(args.out, spec, overwrite=args.overwrite, progress=show_progress(args))
    from vishap.sim.reader import SyntheticSequence

    seq = SyntheticSequence(out)
    gt = seq.gt
    rec = {"out": str(out), "frames": len(seq), "scene": str(gt["scene"]), "seed": int(gt["seed"]),
           "background": str(gt["background"]), "tip_visible_left": float(gt["tip_visible_left"].mean()),
           "tip_visible_right": float(gt["tip_visible_right"].mean())}
    report(args, rec, [f"wrote {rec['frames']} frames of scene {rec['scene']} (seed {rec['seed']}, {rec['background']} "
                       f"background) to {out}",
                       f"  fingertip visible in {rec['tip_visible_left']:.0%} of left, {rec['tip_visible_right']:.0%} "
                       "of right frames; ground truth in gt.npz"])
    return 0


def _check_render_args(spec) -> None:
    """Background and skin tone are checked by the renderer; check them before anything is written."""
    from vishap.sim.hand import skin_tone_rgb
    from vishap.sim.textures import choose_background

    choose_background(spec.background, spec.seed)
    if spec.skin_tone is not None:
        skin_tone_rgb(spec.skin_tone)


def _add_scale_options(p: argparse.ArgumentParser) -> None:
    from vishap.scale.cli import add_engine_options, seed_range

    p.add_argument("--seeds", type=seed_range, default=None, metavar="A:B",
                   help="render seeds A … B-1, one folder seed-NNNNNN each, plus manifest.json under --out "
                        "(a re-run resumes); --seed is then ignored")
    add_engine_options(p)


def _run_seeds(args: argparse.Namespace, spec) -> int:
    from vishap.scale.cli import run_seeds

    return run_seeds(args, spec)
