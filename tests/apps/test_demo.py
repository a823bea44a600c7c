"""End to end: one short wall demo with every fault injected, its outputs, and its replay."""
import json

import numpy as np
import pytest

from vishap.apps import DemoConfig, run_demo
from vishap.apps.log import load_log, read_frame_png, write_frame_png
from vishap.apps.replay import replay

FAULTS = [
    {"kind": "finger_lost", "t_start": 0.80, "t_end": 1.10},
    {"kind": "frames_dropped", "t_start": 1.20, "t_end": 1.30},
    {"kind": "vision_stalled", "t_start": 1.40, "t_end": 2.20},
    {"kind": "nan", "t_start": 2.30, "t_end": 2.45},
    {"kind": "calibration_missing", "t_start": 2.50, "t_end": 2.60},
]

pytestmark = pytest.mark.render


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("wall")
    cfg = DemoConfig(scene="wall", frames=80, width=480, height=360, seed=1, faults=FAULTS)
    summary = run_demo(cfg, out)
    meta, ch = load_log(out)
    return out, summary, meta, ch


def test_outputs_and_summary(run):
    out, summary, meta, ch = run
    for name in ("demo.mp4", "force_depth.png", "timeline.png", "tactile_spectrogram.png", "contact_states.png",
                 "log.npz", "summary.json", "camera_robot.yaml"):
        assert (out / name).is_file(), name
    assert json.loads((out / "summary.json").read_text()) == summary
    for key in ("frames", "tip3d_rms_mm", "contact_lead_time_ms", "contact_position_error_mm", "force_depth_r2",
                "max_force_n", "servo_overruns", "vision_ms_per_pair", "realtime_factor"):
        assert key in summary, key
    assert summary["frames"] == 80 and len(ch["vision"]["t"]) == 80
    assert summary["servo_ticks"] == len(ch["servo"]["t"]) == round(80 / 30 * 1000)
    assert len(ch["tactile"]["t"]) == summary["servo_ticks"]
    assert summary["calibration"]["source"] == "simulation" and summary["calibration"]["poses_used"] >= 3
    import imageio.v2 as imageio

    assert len(imageio.mimread(str(out / "demo.mp4"), memtest=False)) == 80
    # the augmented view: the left camera with the device deleted and the wall drawn in (not the raw frame)
    ar = imageio.mimread(str(out / "ar.mp4"), memtest=False)
    assert len(ar) == 80 and ar[-1].shape[:2] == (360, 480)
    raw = read_frame_png(out / "frames", "left", 79)[:, :, ::-1]
    assert np.abs(ar[-1].astype(float) - raw.astype(float)).mean() > 3.0


def test_frames_show_the_plant_at_their_time(run):
    _, _, _, ch = run
    v, s = ch["vision"], ch["servo"]
    ticks = np.round(v["t"] * 1000).astype(int)
    # the servo row of tick k logs the plant state read at time t_k, before that tick's step
    assert np.array_equal(v["device_q"], s["q"][ticks])
    assert np.allclose(s["t"][ticks], v["t"])


def test_faults_hold_or_retreat_within_one_cycle_and_are_counted(run):
    _, summary, meta, ch = run
    s, sc = ch["servo"], ch["scene"]
    assert summary["reaction_misses"] == 0
    assert summary["nonfinite_commands"] == 0 and summary["force_over_limit"] == 0
    assert np.all(np.isfinite(s["F_cmd"]))
    assert np.max(np.linalg.norm(s["F_cmd"], axis=1)) <= meta["force_limit_n"] + 1e-9
    ev = summary["fault_events"]
    assert ev["frame_dropped"] == summary["frames_dropped"] > 0
    for kind in ("vision_stalled", "nan_input", "calibration_missing"):
        assert ev[kind] >= 1, kind
    tick = {round(t * 1000): i for i, t in enumerate(s["t"])}
    # a NaN or uncalibrated target reaches the servo at a scene tick: that very tick is not tracking
    armed_at = s["t"][np.argmax(s["guard"] != 3)]  # before the first finger estimate the servo just holds
    bad = (~np.all(np.isfinite(sc["X_d"]), axis=1) | ~sc["calibrated"].astype(bool)) & (sc["t"] >= armed_at)
    assert bad.any()
    for t in sc["t"][bad]:
        assert s["guard"][tick[round(t * 1000)]] in (1, 2)
    # a stall longer than retreat_after_s retreats; the device never tracks during the stall
    cfg = meta["config"]
    stall = (s["t"] > 1.40 + cfg["stale_after_s"] + 0.001) & (s["t"] < 2.2)
    assert np.all(s["guard"][stall] != 0) and np.any(s["guard"][stall] == 2)
    # while the finger is out of view, the device does not chase a target
    lost = (s["t"] > 1.0) & (s["t"] < 1.1)
    assert np.all(s["guard"][lost] != 0)


def test_replay_reproduces_vision_world_and_tactile(run, tmp_path):
    from vishap.robot.params import DEFAULT

    out, _, meta, _ = run
    rep = replay(out, out=tmp_path)
    assert rep["identical"] and rep["same_code"], rep
    # the surface hold too, with the device friction the run's hold cancelled
    assert meta["hold_ramp_m"] == DEFAULT.tip_resolution_m
    assert meta["hold_friction_n"] == DEFAULT.coulomb_friction_n and rep["world"]["F_hold"] == 0.0
    for part in ("vision", "world", "tactile"):
        assert rep[part] and all(v == 0.0 for v in rep[part].values()), part
    assert (tmp_path / "replay.json").is_file()
    from vishap.cli import main

    assert main(["replay", str(out / "log.npz"), "--out", str(tmp_path / "cli")]) == 0


def test_replay_detects_a_log_that_differs_from_what_the_core_computes(run, tmp_path):
    """Replay compares its re-run with the demo's real log: one changed force-law or surface-hold sample,
    one changed world target or one changed pixel must each make it report a difference."""
    out, _, _, _ = run
    with np.load(out / "log.npz", allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    law = np.flatnonzero(np.any(arrays["servo/F_law"] != 0, axis=1))
    assert law.size, "the demo rendered no force law"

    def tampered(name, edit):
        d = tmp_path / name
        d.mkdir()
        (d / "frames").symlink_to(out / "frames", target_is_directory=True)
        a = {k: v.copy() for k, v in arrays.items()}
        edit(a)
        np.savez_compressed(d / "log.npz", **a)
        return replay(d)

    def law_edit(a):
        a["servo/F_law"][law[len(law) // 2], 2] += 1e-9

    def hold_edit(a):  # a tick where the renderer holds the face (or, where it never did, one that it did not)
        held = np.flatnonzero(np.any(a["servo/F_hold"] != 0, axis=1))
        a["servo/F_hold"][held[len(held) // 2] if held.size else 0, 2] -= 1e-9

    def world_edit(a):
        i = int(np.flatnonzero(np.all(np.isfinite(a["scene/X_d"]), axis=1))[-1])
        a["scene/X_d"][i, 0] += 1e-9

    rep = tampered("law", law_edit)
    assert not rep["identical"] and rep["world"]["F_law"] > 0 and rep["vision"]["p_cam"] == 0.0
    rep = tampered("hold", hold_edit)
    assert not rep["identical"] and rep["world"]["F_hold"] > 0 and rep["world"]["F_law"] == 0.0
    rep = tampered("world", world_edit)
    assert not rep["identical"] and rep["world"]["X_d"] > 0
    # a changed frame changes what vision finds
    frames = tmp_path / "pix"
    frames.mkdir()
    import shutil

    shutil.copytree(out / "frames", frames / "frames")
    shutil.copy(out / "log.npz", frames / "log.npz")
    k = int(np.flatnonzero(arrays["vision/found"])[len(np.flatnonzero(arrays["vision/found"])) // 2])
    img = read_frame_png(frames / "frames", "left", k)
    img[:] = img[:, ::-1]  # the left view mirrored: the tip moves
    write_frame_png(frames / "frames", "left", k, img)
    rep = replay(frames)
    assert not rep["identical"] and rep["vision"]["uv_left"] > 1.0


@pytest.mark.parametrize("key, value", [("hold_friction_n", float("nan")), ("hold_ramp_m", -1e-5),
                                        ("force_limit_n", float("inf"))])
def test_replay_refuses_a_log_whose_force_settings_are_not_finite_or_negative(run, tmp_path, key, value):
    """A log whose meta holds a NaN, infinite or negative force setting is refused with one error naming the
    log and the field, and writes nothing: replayed, it would put a NaN or a wrong force in every held tick."""
    from vishap._core.errors import ConfigError
    out, _, _, _ = run
    with np.load(out / "log.npz", allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    meta[key] = value
    arrays["meta"] = np.array(json.dumps(meta))
    d = tmp_path / "bad"
    d.mkdir()
    (d / "frames").symlink_to(out / "frames", target_is_directory=True)
    np.savez_compressed(d / "log.npz", **arrays)
    with pytest.raises(ConfigError) as err:
        replay(d, out=tmp_path / "rep")
    assert err.value.field == f"meta.{key}" and str(d / "log.npz") in str(err.value)
    assert not (tmp_path / "rep").exists()


def test_live_loop_renders_the_wall_law_on_the_recorded_frames(run, tmp_path):
    """Live mode (servo cycle in its own process, mailboxes) on the demo's frames played back at 30 Hz,
    the simulated device pressed by the recording's finger: the wall's law must be rendered, and the live
    log replays."""
    from vishap.apps.config import DemoConfig
    from vishap.apps.live_loop import run_live_loop
    from vishap.apps.log import read_frame_png
    from vishap.apps.replay import _rig_from_string
    from vishap.vision.capture import ArraySource

    out, _, meta, ch = run
    v, s = ch["vision"], ch["servo"]
    n = 75  # through the first press (touch at 1.58 s)
    pairs = [(float(t), read_frame_png(out / "frames", "left", k), read_frame_png(out / "frames", "right", k))
             for k, t in enumerate(v["t"][:n])]
    ticks = np.round(v["t"][:n] * 1000).astype(int)
    gt = {"t": v["t"][:n], "tip_robot": v["tip_robot_true"][:n], "tip_cam": v["tip_cam_true"][:n],
          "finger_velocity_robot": s["finger_velocity"][ticks], "finger_dir_robot": np.tile([-0.766, 0.0, -0.643], (n, 1)),
          "tip_visible_left": v["tip_visible"][:n], "tip_visible_right": v["tip_visible"][:n],
          "hand_visible": v["hand_visible"][:n], "T_robot_cam": meta["T_robot_cam_true"]}
    cfg = DemoConfig(scene="wall", seed=1, video=False)
    summary = run_live_loop(cfg, out=tmp_path, source=ArraySource(pairs), rig=_rig_from_string(meta["rig"]),
                            T_robot_cam=np.asarray(meta["T_robot_cam_est"]), gt=gt, device="sim")
    from vishap.apps.log import load_log as _load

    lm, lch = _load(tmp_path)
    assert lm["mode"] == "live" and summary["frames"] == n and summary["servo_steps"] > 0
    assert np.all(np.diff(lch["vision"]["t"]) > 0)  # the servo's clock runs (frames are stamped with it)
    ls = lch["servo"]
    pressed = ls["in_contact"].astype(bool) & (ls["device_depth"] > 0.001)
    assert pressed.sum() > 20, "the simulated finger never pressed the device"
    # while pressed in, the wall's law acts along the normal (800 N/m · depth, within the device's limit)
    assert np.all(ls["law_active"][pressed])
    assert np.allclose(ls["F_law"][pressed, 2], np.minimum(800.0 * ls["device_depth"][pressed], 8.5), rtol=0.05, atol=0.05)
    assert len(lch["tactile"]["t"]) == len(ls["t"]) and np.any(lch["tactile"]["state"] > 0)  # the sleeve ran
    for key in ("force_depth_r2", "tip3d_rms_mm", "fault_events", "reaction_misses"):
        assert key in summary, key
    assert (tmp_path / "force_depth.png").is_file() and (tmp_path / "timeline.png").is_file()
    # one log schema: replay re-runs the live log's vision, scene step and force law bit for bit (a live
    # run stamps a scene row with its frame's own time, which can fall after the tick that used it)
    rep = replay(tmp_path)
    assert rep["identical"], rep
