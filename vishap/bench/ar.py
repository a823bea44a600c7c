"""``vishap bench ar``: the augmented view measured against ground truth (issue 19, item 3).

For each scene a synthetic sequence (:mod:`vishap.sim.sequence`: the scripted finger and the
encountered-type device moving to meet it) is rendered twice per evaluated frame, with and without
the device, from the same renderer settings and camera noise; the one without is the ground truth
of what deletion should show. Auto-exposure is off in both renderers: the dark device would
otherwise change the gain of one rendering and not the other, and the comparison would measure
exposure instead of deletion. The compositor knows the device only through its joint angles (the
inverse kinematics of the drawn end-effector, as encoders would report) and the camera only
through a calibration run in simulation (:class:`vishap.registration.sim.SimCalibration`, 12 poses);
the hand only through the vision's skin segmentation.

* **Deletion** — inside the device's true pixels (label 2): PSNR and SSIM (kornia) against the
  ground truth, and the share of device pixels left visible; for the learned background (this
  compositor: never-seen pixels inpainted by Telea at full or half resolution), plain
  ``cv2.inpaint`` Telea and Navier–Stokes of the same region in every frame, and no deletion.
  The learned fill is split into pixels the background has seen and pixels it never saw (behind
  the static base), where only inpainting is possible.
* **Registration** — the overlaid objects' corners projected through the calibration against
  their projection through the true camera pose (what the renderer draws), in pixels.
* **Occlusion** — over the pixels the objects cover, whether the hand is shown (vision's skin mask)
  against the label images' skin; "objects on top" is the view without occlusion.
* **Cost** — milliseconds per frame of the whole :meth:`ARCompositor.compose` (skin mask included),
  wall clock and the process's CPU time (less sensitive to a busy machine), and per stage; the
  camera period is 33 ms at 30 Hz, the goal half of it.
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "AR view: device deletion (learned background vs cv2.inpaint vs none), overlay registration, occlusion, ms/frame"
QUICK_ARGS = ["--resolution", "320x240", "--frames", "60", "--every", "10", "--scenes", "wall,button"]

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run"]

METHODS = ("learned background", "learned background, half-res inpaint", "cv2.inpaint Telea", "cv2.inpaint NS",
           "no deletion")


def add_arguments(parser) -> None:
    parser.add_argument("--scenes", default="wall,button,fabric", help="scenes (comma-separated)")
    parser.add_argument("--resolution", default="640x480", help="image size WxH")
    parser.add_argument("--frames", type=int, default=150, help="frames per sequence (30 fps)")
    parser.add_argument("--every", type=int, default=5, help="evaluate every n-th frame against ground truth")
    parser.add_argument("--calib-poses", type=int, default=12, help="poses of the simulated camera-robot calibration")
    parser.add_argument("--sweep-poses", type=int, default=12,
                        help="hand-free frames of the arm visiting poses before the sequence (the calibration's sweep)")
    parser.add_argument("--seed", type=int, default=0)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    if a.size == 0:
        return float("nan")
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def _ssim_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    import torch
    from kornia.metrics import ssim

    ta = torch.from_numpy(np.ascontiguousarray(a.transpose(2, 0, 1))).float()[None]
    tb = torch.from_numpy(np.ascontiguousarray(b.transpose(2, 0, 1))).float()[None]
    with torch.no_grad():
        return ssim(ta, tb, 11, max_val=255.0)[0].mean(0).numpy()


def _calibrate(rig, scene: str, poses: int, seed: int) -> tuple[np.ndarray, dict]:
    from vishap.registration.sim import SimCalibration

    sim = SimCalibration(rig=rig, seed=seed, scene=scene)
    try:
        res = sim.run(poses, seed)
    finally:
        sim.close()
    main = res["reprojection_refined"]
    return res["fit"].T, {k: main.get(k) for k in ("rms_mm", "rotation_error_deg", "translation_error_mm",
                                                    "reprojection_rms_px")}


def _device_contact(state, surface_z: float, mount_offset):
    """Contact as the device reports it: its passive object's top face pressed under the surface."""
    from vishap.ar import Contact

    top = np.asarray(state.ee_robot, float) + np.asarray(mount_offset, float)
    depth = surface_z - top[2]
    return Contact(tuple(top), float(depth)) if state.hand_visible and depth > 0 else None


def _sweep(n: int, seed: int) -> list[np.ndarray]:
    """End-effector points the arm visits before the sequence, as in the camera-robot calibration
    (VisHap §2.2: "we move the haptic device around in the field of view"): uniform in the
    reachable box, within the joint limits."""
    from vishap._core.errors import ShapeError
    from vishap.robot import kinematics
    from vishap.robot.params import DEFAULT

    rng = np.random.default_rng([seed, 0xA5])
    lo, hi = np.asarray(DEFAULT.workspace_min), np.asarray(DEFAULT.workspace_max)
    out = []
    while len(out) < n:
        p = lo + rng.random(3) * (hi - lo)
        try:
            if kinematics.within_joint_limits(kinematics.ik(p)):
                out.append(p)
        except ShapeError:
            continue
    return out


def _scene(name: str, res, frames: int, every: int, poses: int, sweep: int, seed: int, out) -> dict:
    import cv2

    from vishap.ar import ARCompositor, LearnedBackground, ViewCamera, device_geometry, inpaint_region, object_corners_robot
    from vishap.robot import kinematics
    from vishap.sim.camera_effects import CameraEffects
    from vishap.sim.renderer import StereoRenderer
    from vishap.sim.sequence import SequenceSpec, frame_state, prepare
    from vishap.world.scene import load_scene

    p = prepare(SequenceSpec(scene=name, frames=frames, seed=seed, width=res[0], height=res[1]))
    T_est, calib = _calibrate(p.rig, name, poses, seed)
    fx = CameraEffects(gain=False)
    with_dev = StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, seed=seed, effects=fx)
    without = StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, seed=seed, effects=fx)
    scene = load_scene(name)
    geo = device_geometry("phantom_premium_1_0", passive_size_m=p.passive.size_m,
                          mount_offset_robot=p.passive.mount_offset_robot)
    ar = ARCompositor(p.rig, T_est, scene, geo, seed=seed)
    half = ARCompositor(p.rig, T_est, scene, geo, seed=seed, background=LearnedBackground(p.rig.image_size, inpaint_half=True))
    hand_free = int(p.trajectory.spec.hand_free_frames)
    acc = {m: {"sq": 0.0, "n": 0, "ssim": [], "visible": [], "ms": []} for m in METHODS}
    split = {"seen": [0.0, 0], "never seen": [0.0, 0]}
    occl = {"this (vision skin mask)": [], "objects on top (no occlusion)": []}
    hand_recall = []
    stage_ms = {k: [] for k in ("total_ms", "skin_ms", "silhouette_ms", "fill_ms", "overlay_ms", "cpu_ms")}
    still = None
    from vishap.sim.device import device_links
    from vishap.sim.state import FrameState

    dwell = 0.5  # s between sweep poses
    no_hand = np.zeros((res[1], res[0]), np.uint8)  # the user keeps the hand out during the sweep
    try:
        for k, ee in enumerate(_sweep(sweep, seed)):
            t = k * dwell
            s0 = FrameState(t=t, tip_robot=np.array([0.3, 0.0, 0.0]), hand_visible=False,
                            device_points_robot=device_links(ee), ee_robot=ee, passive_object=p.passive)
            left = with_dev.render(s0).left
            q = kinematics.ik(ee)
            ar.compose(left, no_hand, q, t)
            half.compose(left, no_hand, q, t)
        t_start = sweep * dwell
        for i, t in enumerate(p.times + t_start):
            state, _ = frame_state(p, float(t - t_start))
            state = replace(state, t=float(t))
            pair = with_dev.render(state)
            q = kinematics.ik(state.ee_robot)  # the encoders' joint angles
            contact = _device_contact(state, p.scene_spec.surface_z_m, p.passive.mount_offset_robot)
            cpu0 = time.process_time()
            view = ar.compose(pair.left, None, q, float(t), contact=contact)
            cpu_ms = 1e3 * (time.process_time() - cpu0)
            if "region" not in ar.last or i < hand_free:
                continue
            stage_ms["cpu_ms"].append(cpu_ms)
            half.delete(pair.left, ar.last["skin"], q, float(t))  # the same skin mask, half-res inpainting
            for k in stage_ms:
                if k != "cpu_ms":
                    stage_ms[k].append(ar.timings.get(k, np.nan))
            if (i - hand_free) % every:
                continue
            truth = without.render(replace(state, device_points_robot=None, ee_robot=None, passive_object=None)).left
            dev = pair.labels_left == 2
            if not dev.any():
                continue
            region = ar.last["region"]
            fills = {"learned background": ar.last["deleted"], "learned background, half-res inpaint": half.last["deleted"]}
            ms = {"learned background": ar.timings["silhouette_ms"] + ar.timings["fill_ms"],
                  "learned background, half-res inpaint": half.timings["silhouette_ms"] + half.timings["fill_ms"]}
            for m, meth in (("cv2.inpaint Telea", "telea"), ("cv2.inpaint NS", "ns")):
                c0 = time.perf_counter()
                fills[m] = inpaint_region(pair.left, region, method=meth)
                ms[m] = ar.timings["silhouette_ms"] + 1e3 * (time.perf_counter() - c0)
            fills["no deletion"], ms["no deletion"] = pair.left, 0.0
            for m, img in fills.items():
                d = (img[dev].astype(np.float64) - truth[dev]) ** 2
                acc[m]["sq"] += float(d.sum())
                acc[m]["n"] += int(d.size)
                acc[m]["ssim"].append(float(_ssim_map(img, truth)[dev].mean()))
                deleted = region > 0 if m != "no deletion" else np.zeros_like(dev)
                acc[m]["visible"].append(float(np.count_nonzero(dev & ~deleted)) / float(dev.sum()))
                acc[m]["ms"].append(ms[m])
            seen = ar.background.count > 0
            for part, sel in (("seen", dev & seen), ("never seen", dev & ~seen)):
                e = (fills["learned background"][sel].astype(np.float64) - truth[sel]) ** 2
                split[part][0] += float(e.sum())
                split[part][1] += int(e.size)
            cover = ar.last["cover"] > 0
            if cover.any():
                hand = pair.labels_left[cover] == 1
                shown = ar.last["skin"][cover] > 0
                occl["this (vision skin mask)"].append((np.count_nonzero(shown == hand), cover.sum()))
                occl["objects on top (no occlusion)"].append((np.count_nonzero(~hand), cover.sum()))
                if hand.any():
                    hand_recall.append((np.count_nonzero(shown & hand), np.count_nonzero(hand)))
            overlap = int(np.count_nonzero((ar.last["skin"] > 0) & cover))  # the still: the hand most over an object
            if still is None or overlap > still[0]:
                still = (overlap, np.hstack([pair.left, ar.last["deleted"], view, truth]))
    finally:
        with_dev.close()
        without.close()
    if still is not None:
        cv2.imwrite(str(out / f"ar_still_{name}.png"), still[1])
    # registration: the corners as drawn (through the calibration) against the true projection
    cam_est, cam_true = ar.camera, ViewCamera(p.rig, p.T_robot_cam, "left")
    corners = np.vstack([object_corners_robot(o) for o in scene.objects])
    err = np.linalg.norm(cam_est.project_robot(corners) - cam_true.project_robot(corners), axis=1)
    methods = {}
    for m, a in acc.items():
        mse = a["sq"] / max(1, a["n"])
        methods[m] = {"deleted_region_psnr_db": 10 * np.log10(255.0 ** 2 / mse) if mse > 0 else float("inf"),
                      "deleted_region_ssim": float(np.mean(a["ssim"])) if a["ssim"] else None,
                      "device_pixels_visible_fraction": float(np.mean(a["visible"])) if a["visible"] else None,
                      "deletion_ms": float(np.median(a["ms"])) if a["ms"] else None}
    psnr_split = {k: (10 * np.log10(255.0 ** 2 / (s / n)) if n else None) for k, (s, n) in split.items()}
    frac_never = split["never seen"][1] / max(1, split["never seen"][1] + split["seen"][1])
    occ = {k: (sum(a for a, _ in v) / max(1, sum(b for _, b in v))) for k, v in occl.items()}
    total = np.array(stage_ms["total_ms"], float)
    return {
        "calibration": calib,
        "evaluated_frames": len(acc["no deletion"]["ms"]),
        "methods": methods,
        "learned_fill_psnr_db_by_part": psnr_split,
        "device_pixels_never_seen_fraction": frac_never,
        "overlay_corner_error_px": {"mean": float(err.mean()), "max": float(err.max())},
        "hand_occlusion_accuracy": occ,
        "hand_pixels_kept_in_front_fraction": (sum(a for a, _ in hand_recall) / max(1, sum(b for _, b in hand_recall))
                                               if hand_recall else None),
        "ms_per_frame": {"median": float(np.nanmedian(total)), "p95": float(np.nanpercentile(total, 95)),
                         **{k: float(np.nanmedian(v)) for k, v in stage_ms.items() if k != "total_ms"}},
    }


def _chart(scenes: dict, out) -> None:
    fig, axes = new_figure(1, 2, figsize=(11, 4.2))
    markers = dict(zip(scenes, "osD^v"))
    colours = dict(zip(METHODS, ("C0", "C9", "C1", "C2", "C3")))
    for name, rec in scenes.items():
        for m, r in rec["methods"].items():
            x = max(r["deletion_ms"], 0.05)
            for ax, key in zip(axes, ("deleted_region_psnr_db", "deleted_region_ssim")):
                ax.scatter([x], [r[key]], c=colours[m], marker=markers[name], s=45,
                           label=f"{m}" if name == next(iter(scenes)) else None)
    for ax, ylab in zip(axes, ("PSNR in the device's silhouette (dB)", "SSIM in the device's silhouette")):
        ax.set_xscale("log")
        ax.set_xlabel("deletion cost per frame (ms, log; silhouette + fill)")
        ax.set_ylabel(ylab)
        ax.grid(alpha=0.3)
    axes[0].axhline(30.0, color="k", lw=0.8, ls="--")
    axes[0].text(axes[0].get_xlim()[0], 30.2, " goal 30 dB", fontsize=8)
    axes[0].legend(fontsize=7, loc="lower right")
    axes[1].set_title("markers: " + ", ".join(f"{n} {markers[n]}" for n in scenes), fontsize=8)
    save_figure(fig, out / "ar_deletion.png")


def run(args) -> dict:
    from pathlib import Path

    out = Path(args.out)
    w, h = (int(v) for v in str(args.resolution).lower().split("x"))
    names = [s.strip() for s in args.scenes.split(",") if s.strip()]
    from vishap._core.results import progress

    scenes = {n: _scene(n, (w, h), args.frames, max(1, args.every), args.calib_poses, args.sweep_poses, args.seed, out)
              for n in progress(names, desc="bench ar", unit="scene", quiet=getattr(args, "quiet", False))}
    _chart(scenes, out)
    this = [s["methods"]["learned background"] for s in scenes.values()]
    occ = [s["hand_occlusion_accuracy"]["this (vision skin mask)"] for s in scenes.values()]
    return {
        "device_pixels_visible_fraction": max(r["device_pixels_visible_fraction"] for r in this),
        "deleted_region_psnr_db": min(r["deleted_region_psnr_db"] for r in this),
        "deleted_region_ssim": min(r["deleted_region_ssim"] for r in this),
        "overlay_corner_error_px": max(s["overlay_corner_error_px"]["max"] for s in scenes.values()),
        "hand_occlusion_accuracy": min(occ),
        "ms_per_frame": float(np.median([s["ms_per_frame"]["median"] for s in scenes.values()])),
        "summary": "worst scene for the fractions, PSNR, SSIM, corner error and occlusion; median over scenes for ms",
        "goals": {"device_pixels_visible_fraction": "< 0.01", "deleted_region_psnr_db": ">= 30",
                  "overlay_corner_error_px": "<= 1", "ms_per_frame": "<= 16.5"},
        "resolution": [w, h], "frames": args.frames, "every": args.every, "seed": args.seed,
        "sweep_poses": args.sweep_poses,
        "scenes": scenes, "machine": machine_info(), "charts": ["ar_deletion.png"],
        "stills": [f"ar_still_{n}.png" for n in names],
    }
