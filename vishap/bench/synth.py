"""``vishap bench synth``: rendering speed of synthetic stereo pairs with labels, and how often the
fingertip is visible in both views per trajectory (issue 3, item 7).

Speed: stereo pairs per second at ``--resolution`` (default 640×480) for the ways of getting the
label images, measured side by side on the same frame states (the wall trajectory's working
phases): labels from the colour pass's alpha (the default, no MSAA), a flat second pass (what a
user of pyrender would do: ``RenderFlags.SEG``) without and with 4× MSAA on the colour pass, and
colour alone (no labels) as the floor; the label-pass cost is the difference. Each configuration
also reports how many label pixels disagree with the flat pass (the exact reference), so the
chart shows speed against label exactness. Camera effects (on by default in sequences) are timed
separately.

Visibility: the fraction of frames whose tip is visible in both views (depth test of
:func:`vishap.sim.sequence.tip_visible`) for each trajectory, over the frames outside the phases in
which it is hidden by design (hand-free, enter, occlusion, leave, away, return), and per phase.
This is geometry: it is rendered without camera effects at ``--vis-resolution`` on every
``--vis-stride``-th frame of one full cycle of each script.
"""
from __future__ import annotations

import time

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "synthetic stereo rendering speed with labels (MSAA, label pass) and tip visibility per trajectory"
QUICK_ARGS = ["--resolution", "320x240", "--pairs", "4", "--vis-resolution", "160x120", "--vis-stride", "15"]

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run"]


def _res(text: str):
    w, h = (int(v) for v in str(text).lower().split("x"))
    return w, h


def add_arguments(parser) -> None:
    parser.add_argument("--resolution", default="640x480", help="image size for the speed part (WxH)")
    parser.add_argument("--pairs", type=int, default=20, help="timed stereo pairs per configuration")
    parser.add_argument("--vis-resolution", default="320x240", help="image size for the visibility part")
    parser.add_argument("--vis-stride", type=int, default=3, help="render every n-th frame for visibility")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenes", default="wall,button,fabric", help="trajectories (one per scene) for visibility")


def _states(res, seed: int, n: int):
    from vishap.sim.sequence import SequenceSpec, frame_state, prepare

    p = prepare(SequenceSpec(scene="wall", frames=400, seed=seed, width=res[0], height=res[1], effects=False))
    times = [t for t in p.times if frame_state(p, float(t))[0].hand_visible][20:]
    pick = np.linspace(0, len(times) - 1, n).astype(int)
    return p, [frame_state(p, float(times[i]))[0] for i in pick]


def _speed(res, n_pairs: int, seed: int) -> dict:
    from vishap.sim.camera_effects import CameraEffects
    from vishap.sim.renderer import StereoRenderer

    p, states = _states(res, seed, n_pairs)
    configs = [  # name, msaa, label mode, effects
        ("colour only (no labels)", 0, "none", False),
        ("labels from alpha (default)", 0, "alpha", False),
        ("labels by flat 2nd pass", 0, "seg", False),
        ("MSAA 4, colour only", 4, "none", False),
        ("MSAA 4 + flat label pass", 4, "seg", False),
        ("MSAA 4, labels from alpha", 4, "alpha", False),
        ("default + camera effects", 0, "alpha", True),
    ]
    renderers = {m: StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, seed=seed, effects=None, msaa=m) for m in (0, 4)}
    fx = StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, seed=seed, effects=CameraEffects(), msaa=0)
    # the exact reference labels: flat pass, no MSAA
    ref = [renderers[0].render(s, labels="seg") for s in states]
    rows = {}
    try:
        for r in (*renderers.values(), fx):
            r.render(states[0])  # warm-up: GL context, shaders, buffers
        # interleave configurations frame by frame so that machine load hits all alike
        durations = {c[0]: [] for c in configs}
        cpu = {c[0]: [] for c in configs}  # CPU time of all the process's threads (llvmpipe's included)
        disagree = {c[0]: [] for c in configs}
        for k, s in enumerate(states):
            # rotate the order per frame: the first render after switching GL context is not favoured
            for name, msaa, mode, effects in configs[k % len(configs):] + configs[:k % len(configs)]:
                r = fx if effects else renderers[msaa]
                t0, c0 = time.perf_counter(), time.process_time()
                out = r.render(s, labels=mode)
                durations[name].append(time.perf_counter() - t0)
                cpu[name].append(time.process_time() - c0)
                if mode != "none":
                    disagree[name].append(0.5 * (np.mean(out.labels_left != ref[k].labels_left)
                                                 + np.mean(out.labels_right != ref[k].labels_right)))
        for name, msaa, mode, effects in configs:
            d = np.array(durations[name])
            rows[name] = {"msaa": msaa, "labels": mode, "effects": effects, "ms_per_pair": 1e3 * float(np.median(d)),
                          "cpu_ms_per_pair": 1e3 * float(np.median(cpu[name])),
                          "pairs_per_s": float(1.0 / np.median(d)),
                          "label_pixels_wrong_pct": (100.0 * float(np.mean(disagree[name])) if disagree[name] else None)}
    finally:
        for r in (*renderers.values(), fx):
            r.close()
    def costs(key):
        c = {name: r[key] for name, r in rows.items()}
        return {
            "alpha_labels_ms": c["labels from alpha (default)"] - c["colour only (no labels)"],
            "flat_label_pass_ms": c["labels by flat 2nd pass"] - c["colour only (no labels)"],
            "flat_label_pass_with_msaa_ms": c["MSAA 4 + flat label pass"] - c["MSAA 4, colour only"],
            "msaa4_colour_ms": c["MSAA 4, colour only"] - c["colour only (no labels)"],
            "camera_effects_ms": c["default + camera effects"] - c["labels from alpha (default)"],
        }

    return {"resolution": list(res), "pairs": n_pairs, "configs": rows, "costs_ms_per_pair": costs("ms_per_pair"),
            "costs_cpu_ms_per_pair": costs("cpu_ms_per_pair")}


def _visibility(scenes, res, stride: int, seed: int) -> dict:
    from vishap.sim.sequence import SequenceSpec, make_renderer, prepare, render_frames
    from vishap.sim.trajectory import HIDDEN_PHASES, PHASES

    out = {}
    for scene in scenes:
        probe = prepare(SequenceSpec(scene=scene, frames=1, seed=seed))
        tr = probe.trajectory
        n_all = int(np.ceil(tr.first_cycle_end_s() * tr.fps))  # one full pass through the script
        spec = SequenceSpec(scene=scene, frames=n_all, seed=seed, width=res[0], height=res[1], effects=False,
                            occlusion=True)
        p = prepare(spec)
        p.times = p.times[::max(1, stride)]
        r = make_renderer(p)
        rows = []
        try:
            for _, _, row in render_frames(p, r):
                rows.append((PHASES[row["phase"]], row["tip_visible_left"], row["tip_visible_right"]))
        finally:
            r.close()
        ph = np.array([x[0] for x in rows])
        both = np.array([x[1] and x[2] for x in rows])
        left = np.array([x[1] for x in rows])
        right = np.array([x[2] for x in rows])
        working = ~np.isin(ph, HIDDEN_PHASES)
        per_phase = {name: {"frames": int((ph == name).sum()), "both_pct": 100.0 * float(both[ph == name].mean())}
                     for name in PHASES if (ph == name).any()}
        out[scene] = {"frames_rendered": len(rows), "working_frames": int(working.sum()),
                      "both_visible_pct_working": 100.0 * float(both[working].mean()),
                      "left_visible_pct_working": 100.0 * float(left[working].mean()),
                      "right_visible_pct_working": 100.0 * float(right[working].mean()),
                      "both_visible_pct_all": 100.0 * float(both.mean()), "per_phase": per_phase,
                      "goal_pct": 90.0, "meets_goal": bool(100.0 * both[working].mean() >= 90.0)}
    return out


def _charts(speed: dict, vis: dict, out_dir) -> list[str]:
    from pathlib import Path

    out_dir = Path(out_dir)
    paths = []
    fig, ax = new_figure(figsize=(7.5, 4.2))
    for i, (name, r) in enumerate(speed["configs"].items()):
        y = r["label_pixels_wrong_pct"]
        if y is None:
            ax.axvline(r["ms_per_pair"], ls=":", color="grey")
            ax.text(r["ms_per_pair"], 0.0, " " + name, rotation=90, va="bottom", fontsize=7, color="grey")
            continue
        ax.plot(r["ms_per_pair"], y, "o")
        ax.annotate(name, (r["ms_per_pair"], y), fontsize=7, xytext=(4, (4, -11, 14)[i % 3]), textcoords="offset points")
    w, h = speed["resolution"]
    ax.set_xlabel(f"ms per stereo pair at {w}×{h} (median)")
    ax.set_ylabel("label pixels differing from the flat pass, %")
    ax.set_title("synthetic stereo: speed vs label exactness")
    paths.append(str(save_figure(fig, out_dir / "synth_speed.png")))
    fig, ax = new_figure(figsize=(8, 4.2))
    from vishap.sim.trajectory import PHASES

    phases = [p for p in PHASES if any(p in v["per_phase"] for v in vis.values())]
    x = np.arange(len(phases))
    width = 0.8 / max(1, len(vis))
    for i, (scene, v) in enumerate(vis.items()):
        vals = [v["per_phase"].get(p, {}).get("both_pct", np.nan) for p in phases]
        ax.bar(x + i * width, vals, width, label=f"{scene} ({v['both_visible_pct_working']:.0f} % working)")
    ax.axhline(90, color="k", ls="--", lw=0.8)
    ax.set_xticks(x + width * (len(vis) - 1) / 2, phases, rotation=40, ha="right", fontsize=8)
    ax.set_ylabel("tip visible in both views, % of frames")
    ax.legend(fontsize=8)
    ax.set_title("fingertip visibility per phase")
    paths.append(str(save_figure(fig, out_dir / "synth_visibility.png")))
    return paths


def run(args) -> dict:
    from pathlib import Path

    from vishap._core.results import progress

    res = _res(args.resolution)
    scenes = [s.strip() for s in str(args.scenes).split(",") if s.strip()]
    # one bar over the parts: the timed renders, then each scene's visibility sweep
    bar = progress(total=1 + len(scenes), desc="bench synth", unit="part", quiet=getattr(args, "quiet", False))
    bar.set_postfix_str("speed")
    speed = _speed(res, max(2, int(args.pairs)), int(args.seed))
    bar.update(1)
    vis = {}
    for scene in scenes:
        bar.set_postfix_str(f"visibility: {scene}")
        vis.update(_visibility([scene], _res(args.vis_resolution), int(args.vis_stride), int(args.seed)))
        bar.update(1)
    bar.close()
    out_dir = Path(args.out or "out/bench/synth")
    charts = _charts(speed, vis, out_dir)
    return {"bench": "synth", "machine": machine_info(), "speed": speed, "visibility": vis, "charts": charts}
