"""``vishap replay LOG``: re-run vision, world and tactile from a demo's log (issue 9 part 4).

The log holds the camera frames (lossless PNG beside ``log.npz``), the device's state at every
servo tick and the contact at every tactile tick — the inputs each of the three stages saw. The
replay builds fresh stages from the logged configuration, feeds them those inputs in the logged
order and compares their outputs with the logged ones:

- vision: every frame that reached vision → ``found``, ``p_cam``, ``uv_left/right``, ``confidence``;
- world: every scene update (the newest vision estimate, mapped by the logged calibration, with the
  device position of that tick) → ``X_d``, ``depth``, ``imminent``, ``in_contact``; and at every
  servo tick the force law's output where the demo evaluated it;
- tactile: every tick's contact sample → the renderer's drive signals and contact state.

Wall-clock timings are not outputs and are not compared. The log records the code that made it
(git commit and a digest of the vision, world, tactile and apps code); replaying with other code warns, since a changed model
or algorithm legitimately changes the outputs. ``identical`` is true when every
compared array matches within ``atol`` (0: bit for bit).
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from vishap._core.errors import ConfigError
from vishap.apps.config import DemoConfig
from vishap.apps.log import SignalLog, load_log, read_frame_png
from vishap.apps.stages import need, tactile_row

__all__ = ["replay", "compare"]


def _rig_from_string(text: str):
    from vishap.vision.rig import StereoRig

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "rig.yaml"
        p.write_text(text)
        return StereoRig.load(p)


def compare(a: dict[str, np.ndarray], b: dict[str, np.ndarray], keys, atol: float) -> dict:
    """Largest absolute difference per key (NaN equal to NaN); ``None`` for a shape mismatch."""
    out = {}
    for k in keys:
        x, y = np.asarray(a[k], float), np.asarray(b[k], float)
        if x.shape != y.shape:
            out[k] = None
            continue
        both_nan = np.isnan(x) & np.isnan(y)
        d = np.where(both_nan, 0.0, np.abs(x - y))
        d = np.where(np.isnan(d), np.inf, d)
        out[k] = float(d.max()) if d.size else 0.0
    return out


def replay(log_path, *, out=None, atol: float = 0.0) -> dict:
    log_path = Path(log_path)
    folder = log_path if log_path.is_dir() else log_path.parent
    meta, ch = load_log(log_path)
    if meta.get("format") != "vishap.demo_log/1":
        raise ConfigError(f"unknown log format {meta.get('format')!r}", file=log_path, field="meta.format")
    cfg = DemoConfig.model_validate(meta["config"])
    frames = folder / "frames"
    if not frames.is_dir():
        raise ConfigError("the log's camera frames are missing (expected a 'frames' folder beside log.npz)", file=frames)
    rig = _rig_from_string(meta["rig"])
    T_est = None if meta.get("T_robot_cam_est") is None else np.asarray(meta["T_robot_cam_est"], float)
    mount = np.asarray(meta["mount_offset"], float)
    r_tip = float(meta["tip_radius_m"])
    n = np.asarray(meta["object"]["normal"], float)
    new = SignalLog(meta)
    report: dict = {"log": str(log_path), "scene": cfg.scene}
    from vishap.apps.log import code_version

    now, then = code_version(), meta.get("code", {})
    report["same_code"] = bool(then) and now.get("stages_sha256") == then.get("stages_sha256")
    if not report["same_code"]:
        import sys

        print(f"vishap replay: warning: the log was made by other stage code (digest {then.get('stages_sha256')}, "
              f"git {then.get('git')}) than this (digest {now['stages_sha256']}, git {now.get('git')}); "
              "outputs may differ", file=sys.stderr)

    # -- vision -----------------------------------------------------------------------------------
    vision_mod = need("vishap.vision.pipeline", "vision")
    capture = need("vishap.vision.capture", "vision capture")
    from vishap.apps.assemble import _vision_result

    pipe = vision_mod.VisionPipeline(rig)
    v = ch["vision"]
    by_t = {}
    for i in range(len(v["t"])):
        t, k = float(v["t"][i]), int(v["index"][i])
        if bool(v["dropped"][i]):
            res = {"found": False, "p_cam": np.full(3, np.nan), "uv_left": np.full(2, np.nan),
                   "uv_right": np.full(2, np.nan), "confidence": 0.0}
        else:
            est = pipe.process(capture.StereoFrame(k, t, read_frame_png(frames, "left", k), read_frame_png(frames, "right", k)))
            res = _vision_result(est)
            if cfg.fault_active("nan", t) and res["found"]:
                res["p_cam"] = np.full(3, np.nan)
        by_t[t] = res
        new.channel("vision").append(t=t, found=res["found"], p_cam=res["p_cam"], uv_left=res["uv_left"],
                                     uv_right=res["uv_right"], confidence=res["confidence"])
    nv = new.channel("vision").arrays()
    report["vision"] = compare(v, nv, ["found", "p_cam", "uv_left", "uv_right", "confidence"], atol)

    # -- world ------------------------------------------------------------------------------------
    from vishap.apps.assemble import make_world

    world_scene = need("vishap.world.scene", "world (scenes)")
    world = make_world(cfg, world_scene.load_scene(cfg.scene), rig, T_est)
    s, sv = ch.get("scene", {}), ch["servo"]
    tick_of = {round(float(t) * cfg.servo_hz): i for i, t in enumerate(sv["t"])}
    scene_rows = len(s.get("t", []))
    j = 0
    inter = None
    lam_state = None
    armed = False
    F_law_new = np.zeros_like(sv["F_law"])
    events = sorted([(float(s["t"][i]), 0, i) for i in range(scene_rows)] +
                    [(float(sv["t"][i]), 1, i) for i in range(len(sv["t"]))])
    for t, kind, i in events:
        if kind == 0:
            r = by_t[float(s["t_sample"][i])]
            p_dev = sv["device_point"][tick_of[round(t * cfg.servo_hz)]]
            calibrated = bool(s["calibrated"][i])
            p_pad = np.full(3, np.nan)
            X = np.full(3, np.nan)
            it = None
            if calibrated and T_est is not None:
                if r["found"] and np.all(np.isfinite(r["p_cam"])):
                    p_pad = r["p_cam"] @ T_est[:3, :3].T + T_est[:3, 3] - r_tip * n
                    it = world.update(float(s["t_sample"][i]), p_pad, p_dev)
                elif not r["found"] and armed:
                    it = world.update(float(s["t_sample"][i]), None, p_dev)
            if it is not None:
                X = np.asarray(it.X_d, float)
                inter = it
            armed = armed or (not calibrated) or r["found"]
            new.channel("scene").append(t=t, finger_robot=p_pad, X_d=X, depth=np.nan if it is None else float(it.depth),
                                        imminent=bool(it is not None and it.imminent),
                                        in_contact=bool(it is not None and it.in_contact))
        else:
            F, lam, _ = world.contact_render(sv["device_point"][i], sv["v_device"][i],
                                             inter if sv["guard"][i] in (0, 1) else None)
            if F is not None:
                F_law_new[i] = F
            if lam != lam_state:
                if lam is None and world.law is not None:
                    world.law.reset()
                lam_state = lam
    if scene_rows:
        ns = new.channel("scene").arrays()
        report["world"] = compare(s, ns, ["finger_robot", "X_d", "depth", "imminent", "in_contact"], atol)
    report["world"] = {**report.get("world", {}), "F_law": compare({"F": sv["F_law"]}, {"F": F_law_new}, ["F"], atol)["F"]}

    # -- tactile ----------------------------------------------------------------------------------
    tac = ch.get("tactile", {})
    if len(tac.get("t", [])):
        from vishap.apps.assemble import _build_tactile, _contact_sample
        from vishap.apps.script import script_for

        renderer, state_of = _build_tactile(cfg, world.scene)
        finger_dir = script_for(cfg.scene, hidden_s=0.0).finger_dir
        obj = world.scene.objects[0]
        rows = SignalLog().channel("tactile")
        for i in range(len(tac["t"])):
            k = tick_of[round(float(tac["t"][i]) * cfg.servo_hz)]
            smp = _contact_sample(obj, float(tac["t"][i]), sv["finger_point"][k], sv["finger_velocity"][k], sv["F_contact"][k], finger_dir)
            o = renderer.step(smp)
            rows.append(t=float(tac["t"][i]), state=state_of(o), **tactile_row(o))
        nt = rows.arrays()
        keys = [k for k in nt if k != "t" and k in tac]
        report["tactile"] = compare(tac, nt, keys, atol)
        new.channels["tactile"] = rows

    worst = [x for part in ("vision", "world", "tactile") for x in report.get(part, {}).values()]
    report["max_abs_difference"] = None if any(x is None for x in worst) else (max(worst) if worst else 0.0)
    report["identical"] = all(x is not None and x <= atol for x in worst)
    if out is not None:
        o = Path(out)
        o.mkdir(parents=True, exist_ok=True)
        new.save(o / "replay_log.npz")
        (o / "replay.json").write_text(json.dumps(report, indent=1) + "\n")
    return report
