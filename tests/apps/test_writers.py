import json

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.apps.log import SignalLog, load_log, read_frame_png, write_frame_png
from vishap.apps.overlay import VideoWriter, draw_overlay, object_outline_robot
from vishap.apps.plots import plot_contact_states, plot_force_depth, plot_spectrogram, plot_timeline
from vishap.vision.rig import StereoRig


def test_log_round_trip(tmp_path):
    log = SignalLog({"scene": "wall", "T": np.eye(4)})
    for k in range(5):
        log.channel("servo").append(t=k * 1e-3, q=np.arange(3) * k, flag=bool(k % 2))
    log.channel("vision").append(t=0.0, p_cam=np.full(3, np.nan))
    log.save(tmp_path / "log.npz")
    meta, ch = load_log(tmp_path)
    assert meta["scene"] == "wall" and meta["T"] == np.eye(4).tolist()
    assert ch["servo"]["q"].shape == (5, 3) and ch["servo"]["flag"].dtype == bool
    assert np.isnan(ch["vision"]["p_cam"]).all()
    with pytest.raises(ValueError):
        log.channel("servo").append(t=1.0)
    with pytest.raises(ConfigError, match="not found"):
        load_log(tmp_path / "nope")


def test_frame_png_lossless(tmp_path, rng):
    img = rng.integers(0, 256, (12, 16, 3), dtype=np.uint8)
    write_frame_png(tmp_path, "left", 3, img)
    assert np.array_equal(read_frame_png(tmp_path, "left", 3), img)
    with pytest.raises(ConfigError, match="000004.png"):
        read_frame_png(tmp_path, "left", 4)


def test_overlay_draws_projected_geometry(tmp_path):
    rig = StereoRig.from_fov(160, 120, 60.0, 0.06)
    outline = object_outline_robot([0.2, 0.0, -0.15], [0, 0, 1], [0.12, 0.16])
    assert np.allclose(outline[0], outline[-1]) and np.allclose(outline[:, 2], -0.15)
    blank = np.zeros((120, 160, 3), np.uint8)
    img = draw_overlay(blank, blank, rig=rig, T_cam_robot=np.eye(4), tip_uv=(np.array([80.0, 60.0]), None),
                       device_points_robot=np.array([[0, 0, 0.4], [0.02, 0.02, 0.45]]),
                       object_outlines_robot=[np.array([[-0.05, 0, 0.5], [0.05, 0, 0.5]])], lines=["t=0.000"])
    assert img.shape == (120, 320, 3)
    assert img[60, 80].tolist() != [0, 0, 0] or img[60, 85].any()   # tip cross drawn in the left view
    assert img[:, 160:].any()                                        # device/object drawn in the right view
    with VideoWriter(tmp_path / "v.mp4", 30) as w:
        for k in range(4):
            w.write(np.roll(img, k, axis=1))
    assert w.frames == 4 and (tmp_path / "v.mp4").stat().st_size > 1000
    import imageio.v2 as imageio

    frames = imageio.mimread(str(tmp_path / "v.mp4"))
    assert len(frames) == 4 and frames[0].shape == (120, 320, 3)


def test_plots_write_pngs(tmp_path):
    t = np.arange(0, 1, 1e-3)
    depth = np.clip(np.sin(2 * np.pi * t) * 0.004, -0.01, None)
    force = np.where(depth > 0, 900 * depth, 0.0)
    assert plot_force_depth(tmp_path / "fd.png", depth, force, title="wall").stat().st_size > 0
    servo = {"t": t, "finger_point": np.c_[t * 0, t * 0, depth], "device_point": np.c_[t * 0, t * 0, depth],
             "X_d": np.zeros((t.size, 3)), "F_contact": np.c_[t * 0, t * 0, force], "F_cmd": np.c_[t * 0, t * 0, force],
             "guard": (t > 0.5).astype(int)}
    vision = {"t": t[::33], "found": np.ones(t[::33].size, bool), "finger_robot": servo["finger_point"][::33]}
    assert plot_timeline(tmp_path / "tl.png", servo, vision, title="x").stat().st_size > 0
    sig = np.sin(2 * np.pi * 250 * t) * (t > 0.3)
    assert plot_spectrogram(tmp_path / "sp.png", t, sig, 1000.0, title="s").stat().st_size > 0
    codes = (t * 4).astype(int) % 4
    assert plot_contact_states(tmp_path / "cs.png", t, codes, ["none", "conc", "dist", "slip"], force,
                               title="c").stat().st_size > 0
