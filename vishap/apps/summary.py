"""``summary.json`` and the plots of a demo run, computed from its logged signals.

:func:`summarize` reads only the log (plus the run's wall-clock figures), so a replayed log gives
the same figures. Keys (issue 9 part 2): ``frames``, ``tip3d_rms_mm``, ``contact_lead_time_ms``
(minimum over approaches), ``contact_position_error_mm``, ``force_depth_r2`` (wall),
``max_force_n``, ``servo_overruns``, ``vision_ms_per_pair``, ``realtime_factor``, and the fault
counts.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from vishap.apps.metrics import approaches, force_depth_r2, tip3d_errors_mm
from vishap._core.results import to_jsonable

__all__ = ["summarize", "write_plots", "write_outputs", "summary_lines"]


def _nanmedian(x) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.median(x)) if x.size else float("nan")


def summarize(meta: dict, ch: dict[str, dict[str, np.ndarray]], *, wall: dict | None = None,
              stats: dict | None = None, guard_counts: dict | None = None) -> dict:
    cfg = meta["config"]
    vis = ch.get("vision", {})
    servo = ch.get("servo", {})
    out: dict = {"scene": cfg["scene"], "seed": cfg["seed"], "image_size": [cfg["width"], cfg["height"]],
                 "frames": int(len(vis.get("t", []))), "duration_s": float(servo["t"][-1] + 1e-3) if len(servo.get("t", [])) else 0.0}
    # vision accuracy: frames where the tip is visible in both views
    if len(vis.get("t", [])):
        vis_ok = vis["tip_visible"].astype(bool) & ~vis["dropped"].astype(bool)
        found = vis["found"].astype(bool)
        err = tip3d_errors_mm(vis["p_cam"], vis["tip_cam_true"], vis_ok & found)
        out.update(
            tip3d_rms_mm=float(np.sqrt(np.mean(err ** 2))) if err.size else None,
            tip3d_median_mm=float(np.median(err)) if err.size else None,
            tip_visible_frames=int(vis_ok.sum()),
            # None, not 0, when no frame shows the fingertip: there was nothing to detect
            detection_rate=float((vis_ok & found).sum() / vis_ok.sum()) if vis_ok.any() else None,
            false_detections=int((found & ~vis["tip_visible"].astype(bool)).sum()),
            vision_ms_per_pair=_nanmedian(vis["vision_ms"]),
            render_ms_per_pair=_nanmedian(vis["render_ms"]),
        )
    if len(servo.get("t", [])):
        t = servo["t"]
        n = np.asarray(meta["object"]["normal"], float)
        on_surface = servo["finger_point"] + np.outer(servo["finger_depth"], n)
        if meta["object"].get("target") == "centre":  # a key: the device belongs at its centre (VisHap §2.3)
            on_surface = np.broadcast_to(np.asarray(meta["object"]["centre"], float), on_surface.shape)
        aps = approaches(t, servo["finger_depth"], on_surface, servo["device_point"])
        leads = [a.lead_time_s for a in aps]
        known = [x for x in leads if x is not None]
        out["approaches"] = [{"t_touch_s": a.t_touch, "lead_time_ms": None if a.lead_time_s is None else 1e3 * a.lead_time_s,
                              "position_error_mm": 1e3 * a.position_error_m} for a in aps]
        out["contact_lead_time_ms"] = (1e3 * min(known) if len(known) == len(leads) and known else None)
        out["device_in_place_rate"] = float(sum(1 for x in leads if x is not None and x > 0) / len(leads)) if leads else None
        out["contact_position_error_mm"] = float(np.mean([1e3 * a.position_error_m for a in aps])) if aps else None
        out["contact_position_error_mm_max"] = float(max(1e3 * a.position_error_m for a in aps)) if aps else None
        pressed = servo["in_contact"].astype(bool)
        Fn = servo["F_contact"] @ n
        a, b, r2 = force_depth_r2(servo["device_depth"][pressed], Fn[pressed])
        out["force_depth_r2"] = r2 if np.isfinite(r2) else None
        out["force_depth_slope_n_per_mm"] = a * 1e-3 if np.isfinite(a) else None
        out["max_force_n"] = float(np.max(np.linalg.norm(servo["F_cmd"], axis=1)))
        out["max_contact_force_n"] = float(np.max(np.linalg.norm(servo["F_contact"], axis=1)))
        out["force_limit_n"] = meta["force_limit_n"]
        if "saturated" in servo:
            # ticks on which the controller clipped its force, and ticks on which its heating estimate
            # held it to the continuous force (robot controller: |F|² low-passed vs continuous²)
            out["force_saturated_ticks"] = int(np.sum(servo["saturated"]))
            cont = meta.get("continuous_force_n")
            if cont:
                out["thermal_limited_ticks"] = int(np.sum(servo["heat_n2"] > cont * cont))
        out["servo_ticks"] = int(t.size)
        tick_us = servo["tick_us"]
        out["servo_tick_us_median"] = float(np.median(tick_us))
        out["servo_overruns"] = int(np.sum(tick_us > 1e6 / cfg["servo_hz"]))
        out["guard_hold_ticks"] = int(np.sum(servo["guard"] == 1))
        out["guard_retreat_ticks"] = int(np.sum(servo["guard"] == 2))
    tac = ch.get("tactile", {})
    if len(tac.get("t", [])):
        codes = tac["state"].astype(int)
        out["tactile_ticks"] = int(tac["t"].size)
        out["tactile_state_ticks"] = {name: int(np.sum(codes == k)) for name, k in
                                      (("none", 0), ("concentrated", 1), ("distributed", 2), ("slip", 3))}
    out["faults_injected"] = [f"{f['kind']}:{f['t_start']}:{f['t_end']}" for f in cfg.get("faults", [])]
    if guard_counts is not None:
        out["fault_events"] = dict(guard_counts)
    if stats is not None:
        out.update({k: int(v) for k, v in stats.items()})
    if "record_seq" in servo:
        out["reaction_misses"] = reaction_misses(meta, ch)
    if wall is not None:
        sim_s = out["duration_s"]
        loop = wall["total"] - wall["render"] - wall.get("io", 0.0)
        out["wall_s"] = wall["total"]
        out["wall_s_by_stage"] = {k: v for k, v in wall.items() if k != "total"}
        out["realtime_factor"] = sim_s / loop if loop > 0 else None
        out["realtime_factor_with_render"] = sim_s / wall["total"] if wall["total"] > 0 else None
    out["calibration"] = meta.get("calibration")
    from vishap.apps.demos import demo_module

    out.update(demo_module(cfg["scene"]).extra_summary(meta, ch))
    return out


def write_plots(out: Path, meta: dict, ch: dict) -> list[str]:
    from vishap.apps.plots import plot_contact_states, plot_force_depth, plot_spectrogram, plot_timeline

    scene = meta["config"]["scene"]
    servo, vis, tac = ch.get("servo", {}), ch.get("vision", {}), ch.get("tactile", {})
    n = np.asarray(meta["object"]["normal"], float)
    files = []
    if len(servo.get("t", [])):
        pressed = servo["in_contact"].astype(bool)
        files.append(plot_force_depth(out / "force_depth.png", servo["device_depth"][pressed],
                                      (servo["F_contact"] @ n)[pressed],
                                      title=f"{scene}: force along the normal vs depth (VisHap Fig. 6)",
                                      fit=scene != "button"))
        scene_ch = ch.get("scene", {})
        vis_robot = {"t": scene_ch.get("t_sample", np.zeros(0)),
                     "found": np.all(np.isfinite(scene_ch.get("finger_robot", np.zeros((0, 3)))), axis=1),
                     "finger_robot": scene_ch.get("finger_robot", np.zeros((0, 3)))}
        files.append(plot_timeline(out / "timeline.png", servo, vis_robot, title=f"{scene} demo", normal=n))
    if len(tac.get("t", [])):
        if "regions" in tac and "fs" in tac:
            sig = tac["regions"].astype(float).sum(axis=1).reshape(-1)   # the three sleeve actuators, 10 kHz
            fs = float(tac["fs"][0])
            files.append(plot_spectrogram(out / "tactile_spectrogram.png", tac["t"], sig, fs,
                                          title=f"{scene}: sleeve drive (sum of the 3 regional actuators)"))
        files.append(plot_contact_states(out / "contact_states.png", tac["t"], tac["state"],
                                         ["none", "concentrated", "distributed", "slip"], tac["normal_force"],
                                         title=f"{scene}: contact state (tactile classifier)"))
    return [str(Path(f).name) for f in files]


def write_outputs(out: Path, log, *, wall: dict | None = None, stats: dict | None = None,
                  guard_counts: dict | None = None) -> dict:
    """Save ``log.npz``, the plots and ``summary.json`` of a finished run (batch or live) into ``out``."""
    from vishap.apps.log import load_log

    out = Path(out)
    log_path = log.save(out / "log.npz")
    meta, ch = load_log(log_path)
    summary = summarize(meta, ch, wall=wall, stats=stats, guard_counts=guard_counts)
    summary["plots"] = write_plots(out, meta, ch)
    summary["files"] = sorted(p.name for p in out.iterdir() if p.is_file()) + (["frames/"] if (out / "frames").is_dir() else [])
    summary = to_jsonable(summary)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def summary_lines(summary: dict, out) -> list[str]:
    """The few lines a demo shows on the terminal: the figures that matter and where the files are
    (every figure is in ``summary.json``)."""
    def num(key, fmt, unit=""):
        v = summary.get(key)
        return "n/a" if v is None else f"{v:{fmt}}{unit}"

    mode = summary.get("mode", "batch")
    lines = [f"demo {summary['scene']} ({mode}, seed {summary['seed']}): {summary['frames']} frames, "
             f"{num('duration_s', '.2f', ' s')} simulated, realtime factor {num('realtime_factor', '.2f')}"]
    lines.append(f"  vision: tip 3-D RMS {num('tip3d_rms_mm', '.2f', ' mm')}, detection rate "
                 f"{num('detection_rate', '.0%')}, {num('vision_ms_per_pair', '.1f', ' ms')} per pair")
    aps = summary.get("approaches") or []
    lines.append(f"  device: {len(aps)} approach(es), lead time {num('contact_lead_time_ms', '+.0f', ' ms')}, "
                 f"contact position error {num('contact_position_error_mm', '.2f', ' mm')}, "
                 f"max force {num('max_force_n', '.2f', ' N')}")
    if summary.get("force_depth_r2") is not None:
        lines.append(f"  force vs depth R² {summary['force_depth_r2']:.4f}")
    cal = summary.get("calibration") or {}
    if cal.get("error"):
        lines.append(f"  calibration: {cal['error']}")
    retreat = summary.get("guard_retreat_ticks") or 0
    if retreat:
        lines.append(f"  guard: device retreated on {retreat} of {summary.get('servo_ticks', '?')} servo ticks")
    lines.append(f"  files in {out}: summary.json (every figure), log.npz, {', '.join(summary.get('plots', []))}")
    return lines


def reaction_misses(meta: dict, ch: dict) -> int:
    """Servo ticks that tracked a target the log shows was bad: non-finite, uncalibrated, older than
    the configured ``stale_after_s``, below the guard's confidence floor or made from a frame where
    vision lost the finger (logs that predate the ``lost`` flag lack it). Computed from the logged
    records the servo used (``servo/record_seq`` → ``scene`` row), independently of the guard."""
    servo, scene = ch.get("servo", {}), ch.get("scene", {})
    if not len(servo.get("t", [])):
        return 0
    from vishap.runtime.safety import TargetGuard

    cfg = meta["config"]
    seq = np.asarray(servo["record_seq"], int)
    track = (np.asarray(servo["guard"]) == 0) & (seq > 0)
    if not track.any():
        return 0
    row = {int(s): i for i, s in enumerate(scene["seq"])}
    idx = np.array([row.get(int(s), -1) for s in seq[track]])
    known = idx >= 0  # tracking a record the log never saw is a miss by itself
    i, t = idx[known], servo["t"][track][known]
    bad = (~np.all(np.isfinite(scene["X_d"][i]), axis=1) | ~scene["calibrated"][i].astype(bool)
           | (t - scene["t_sample"][i] > cfg["stale_after_s"] + 1e-9)
           | (scene["confidence"][i] < TargetGuard.min_confidence))
    if "lost" in scene:
        bad |= scene["lost"][i].astype(bool)
    return int(bad.sum() + np.sum(~known))
