"""``vishap replay LOG``: re-run vision, world and tactile from a demo's log (issue 9 part 4).

The log holds the camera frames (lossless PNG beside ``log.npz``), the device's state at every
servo tick and the contact at every tactile tick — the inputs each of the three stages saw. The
replay builds fresh stages from the logged configuration, feeds them those inputs in the logged
order and compares their outputs with the logged ones:

- vision: every frame that reached vision → ``found``, ``p_cam``, ``uv_left/right``, ``confidence``;
- scene step (:class:`vishap.runtime.core.SceneStep`, the same code the run used): every scene
  update (the newest vision estimate, mapped by the logged calibration, with the device position of
  that update) → ``X_d``, ``depth``, ``subject``, ``imminent``, ``in_contact``; and at every servo tick
  the servo step's force law, surface hold and object-gain state (:class:`~vishap.runtime.core.ContactRenderer`)
  on the record that tick used, the device state and the guard's action;
- tactile: every tick's contact sample (:func:`vishap.apps.cycle.contact_sample`) → the renderer's
  drive signals and contact state.

Batch and live logs share the schema, so both replay (a live log needs its frames saved).

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

__all__ = ["replay", "compare", "summary_lines"]


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


def summary_lines(report: dict, atol: float = 0.0) -> list[str]:
    """The terminal's few lines: the verdict and, when not identical, which outputs differ."""
    worst = report.get("max_abs_difference")
    lines = [f"replay of {report['log']} ({report['scene']}): "
             + ("identical" if report["identical"] else "DIFFERENT")
             + ("" if worst is None else f", largest difference {worst:.3g}")
             + ("" if report.get("same_code") else " (the log was made by other code)")]
    if not report["identical"]:
        differ = [f"{part}.{k}" for part in ("vision", "world", "tactile")
                  for k, v in report.get(part, {}).items() if v is None or v > atol]
        lines.append(f"  differing: {', '.join(differ)}")
    return lines


def replay(log_path, *, out=None, atol: float = 0.0, progress: bool = False) -> dict:
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
    from vishap.apps.assemble import make_scene_step, make_tactile, make_world, vision_result
    from vishap.vision.capture import StereoFrame
    from vishap.vision.pipeline import VisionPipeline
    from vishap.world.scene import load_scene

    pipe = VisionPipeline(rig)
    v = ch["vision"]
    by_t = {}
    from vishap._core.results import progress as bar

    for i in bar(range(len(v["t"])), desc="replay", unit="frame", quiet=not progress):
        t, k = float(v["t"][i]), int(v["index"][i])
        if bool(v["dropped"][i]):
            res = {"found": False, "lost": False, "p_cam": np.full(3, np.nan), "uv_left": np.full(2, np.nan),
                   "uv_right": np.full(2, np.nan), "confidence": 0.0}
        else:
            res = vision_result(pipe.process(StereoFrame(k, t, read_frame_png(frames, "left", k),
                                                         read_frame_png(frames, "right", k))))
            if cfg.fault_active("nan", t) and res["found"]:
                res["p_cam"] = np.full(3, np.nan)
        by_t[t] = res
        new.channel("vision").append(t=t, found=res["found"], lost=res["lost"], p_cam=res["p_cam"],
                                     uv_left=res["uv_left"], uv_right=res["uv_right"], confidence=res["confidence"])
    nv = new.channel("vision").arrays()
    report["vision"] = compare(v, nv, [k for k in ("found", "lost", "p_cam", "uv_left", "uv_right", "confidence")
                                       if k in v], atol)

    # -- scene step and the servo step's force law, in the logged order ------------------------------
    from vishap.apps.loop import log_scene_row
    from vishap.runtime.core import GUARD_CODES, ContactRenderer, TargetRecord, finger_approach

    scene = load_scene(cfg.scene)
    scene_step = make_scene_step(make_world(cfg, scene, rig, T_est), T_est)
    try:
        contact = ContactRenderer(scene.objects, max_force_n=meta["force_limit_n"], dt=1.0 / cfg.servo_hz,
                                  hold_friction_n=meta.get("hold_friction_n", 0.0),
                                  hold_ramp_m=meta.get("hold_ramp_m", 0.0))
    except ConfigError as e:  # named as the log's meta holds it
        field = f"meta.{'force_limit_n' if e.field == 'max_force_n' else e.field}"
        raise ConfigError(e.reason, file=folder / "log.npz" if log_path.is_dir() else log_path, field=field) from None
    action_of = {code: name for name, code in GUARD_CODES.items()}
    s, sv = ch.get("scene", {}), ch["servo"]
    records = {0: TargetRecord()}  # by sequence number; 0: the servo had no record yet
    F_law_new = np.zeros_like(sv["F_law"])
    F_hold_new = np.zeros_like(sv["F_law"])
    lam_new = np.zeros(len(sv["t"]))
    # the scene step reads only the log (vision, the device point it used) and the servo ticks only the
    # records it made, so the rows go first, then the ticks: a live run stamps a row with its frame's
    # own (continuous) time, which can fall after the first tick that already used the row's record
    for i, t in enumerate(s.get("t", [])):
        r = by_t[float(s["t_sample"][i])]
        rec, inter, p_pad = scene_step.step(float(s["t_sample"][i]), r["found"], r["p_cam"], r["confidence"],
                                            s["device_point"][i], calibrated=bool(s["calibrated"][i]),
                                            lost=r["lost"])
        records[rec.seq] = rec
        log_scene_row(new, float(t), rec, inter, p_pad, s["device_point"][i], mount, 0.0)
    for i in range(len(sv["t"])):
        rec = records[int(sv["record_seq"][i])]
        t_i, p_i = float(sv["t"][i]), sv["device_point"][i]
        _, touch_in, _ = finger_approach(rec, t_i, p_i, None if rec.subject < 0 else scene.objects[rec.subject].normal)
        F, _, _ = contact.update(t_i, p_i, sv["v_device"][i], rec.subject, rec.imminent, rec.in_contact,
                                 action_of[int(sv["guard"][i])], touch_in)
        if F is not None:
            F_law_new[i] = F
        if contact.F_hold is not None:
            F_hold_new[i] = contact.F_hold
        lam_new[i] = contact.state_code
    if len(s.get("t", [])):
        ns = new.channel("scene").arrays()
        report["world"] = compare(s, ns, ["finger_robot", "X_d", "depth", "imminent", "in_contact", "subject"], atol)
    report["world"] = {**report.get("world", {}), "F_law": compare({"F": sv["F_law"]}, {"F": F_law_new}, ["F"], atol)["F"]}
    if "F_hold" in sv:  # the surface hold, from the same renderer
        report["world"]["F_hold"] = compare(sv, {"F_hold": F_hold_new}, ["F_hold"], atol)["F_hold"]
    if "lambda_state" in sv:  # the object gain's state, from the same scheduler on the logged inputs
        report["world"]["lambda_state"] = compare(sv, {"lambda_state": lam_new}, ["lambda_state"], atol)["lambda_state"]

    # -- tactile ----------------------------------------------------------------------------------
    tac = ch.get("tactile", {})
    if len(tac.get("t", [])):
        from vishap.apps.cycle import contact_sample, tactile_row, tactile_state

        renderer = make_tactile(cfg, scene)
        finger_dir = meta.get("sleeve_finger_dir")
        tick_of = {round(float(t) * cfg.servo_hz): i for i, t in enumerate(sv["t"])}
        rows = SignalLog().channel("tactile")
        for i in range(len(tac["t"])):
            t = float(tac["t"][i])
            k = tick_of[round(t * cfg.servo_hz)]
            smp = contact_sample(scene.objects[0], t, sv["device_point"][k], sv["v_device"][k],
                                 records[int(sv["record_seq"][k])], sv["F_contact"][k], finger_dir)
            o = renderer.step(smp)
            rows.append(t=t, state=tactile_state(o), **tactile_row(o))
        nt = rows.arrays()
        keys = [k for k in nt if k != "t" and k in tac]
        report["tactile"] = compare(tac, nt, keys, atol)
        new.channels["tactile"] = rows

    worst = [x for part in ("vision", "world", "tactile") for x in report.get(part, {}).values()]
    report["max_abs_difference"] = None if any(x is None for x in worst) else (max(worst) if worst else 0.0)
    report["identical"] = all(x is not None and x <= atol for x in worst)
    if out is not None:  # the command's output folder (a temporary one, renamed when complete)
        o = Path(out)
        o.mkdir(parents=True, exist_ok=True)
        new.save(o / "replay_log.npz")
        (o / "replay.json").write_text(json.dumps(report, indent=1) + "\n")
    return report
