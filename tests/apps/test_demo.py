"""End to end: one short wall demo with every fault injected, its outputs, and its replay."""
import json

import numpy as np
import pytest

pytest.importorskip("vishap.sim.renderer", reason="the synthetic renderer is not installed")

from vishap.apps import DemoConfig, run_demo  # noqa: E402
from vishap.apps.log import load_log  # noqa: E402
from vishap.apps.replay import replay  # noqa: E402

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
    out, _, _, _ = run
    rep = replay(out, out=tmp_path)
    assert rep["identical"] and rep["same_code"], rep
    for part in ("vision", "world", "tactile"):
        assert rep[part] and all(v == 0.0 for v in rep[part].values()), part
    assert (tmp_path / "replay.json").is_file()
    from vishap.cli import main

    assert main(["replay", str(out / "log.npz"), "--out", str(tmp_path / "cli")]) == 0


def test_live_loop_on_the_recorded_frames(run, tmp_path):
    """The live loop (servo in its own process, mailboxes) on the demo's frames played back at 30 Hz."""
    from vishap.apps.live_loop import run_live_loop
    from vishap.apps.log import read_frame_png
    from vishap.apps.replay import _rig_from_string
    from vishap.vision.capture import ArraySource

    out, _, meta, ch = run
    t = ch["vision"]["t"][:45]
    pairs = [(float(ti), read_frame_png(out / "frames", "left", k), read_frame_png(out / "frames", "right", k))
             for k, ti in enumerate(t)]
    summary = run_live_loop("wall", out=tmp_path, source=ArraySource(pairs), rig=_rig_from_string(meta["rig"]),
                            T_robot_cam=np.asarray(meta["T_robot_cam_est"]), device_path="vishap.robot.plant:MujocoPlant",
                            duration_s=10.0, realtime=False)
    assert summary["frames"] == 45 and summary["servo_steps"] > 0
    from vishap.apps.log import load_log as _load

    live = _load(tmp_path)[1]["frames"]
    assert np.all(np.diff(live["t"]) > 0)  # the servo's clock runs (frames are stamped with it)
    assert summary["detection_rate"] > 0.3
    assert sum(summary["actions"].values()) == 45
    assert (tmp_path / "log.npz").is_file() and (tmp_path / "summary.json").is_file()
