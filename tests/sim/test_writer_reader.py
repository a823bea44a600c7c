"""Writing, reading back, determinism and bad input of ``vishap synth``."""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.cli import main
from vishap.sim.reader import SyntheticSequence
from vishap.sim.sequence import SequenceSpec, generate
from vishap.sim.writer import write_sequence
from vishap.vision.rig import StereoRig

ARGS = ["synth", "--scene", "wall", "--frames", "3", "--seed", "3", "--resolution", "160x120", "--quiet"]


def _digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(parent: Path) -> list[str]:
    return sorted(p.name for p in parent.iterdir())


@pytest.mark.render
def test_same_seed_same_bytes_and_reader_round_trip(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    extra = ["--hand-free", "1", "--lighting", "step"]
    assert main(ARGS + extra + ["--out", str(a)]) == 0
    assert main(ARGS + extra + ["--out", str(b)]) == 0
    da, db = _digest(a), _digest(b)
    assert da == db
    names = set(da)
    for sub in ("left", "right", "labels/left", "labels/right"):
        assert {f"{sub}/{i:06d}.png" for i in range(3)} <= names
    assert {"rig.yaml", "gt.npz"} <= names and len(names) == 14
    assert _leftovers(tmp_path) == ["a", "b"]

    seq = SyntheticSequence(a)
    assert len(seq) == 3 and seq.rig.image_size == (160, 120)
    assert seq.rig.equals(StereoRig.from_fov(160, 120, 60.0, 0.06))
    gt = seq.gt
    for k, shape in (("t", (3,)), ("tip_cam", (3, 3)), ("tip_robot", (3, 3)), ("tip_uv_left", (3, 2)),
                     ("tip_uv_right", (3, 2)), ("tip_visible_left", (3,)), ("tip_visible_right", (3,)),
                     ("finger_velocity_robot", (3, 3)), ("ee_robot", (3, 3)), ("T_robot_cam", (4, 4))):
        assert gt[k].shape == shape, k
    assert str(gt["scene"]) == "wall" and int(gt["seed"]) == 3 and float(gt["tip_radius"]) == 0.008
    assert float(gt["exposure_s"]) == 0.012  # the camera model's own exposure
    np.testing.assert_allclose(seq.T_robot_cam, gt["T_robot_cam"])
    # the files hold what the in-memory generator yields
    spec = SequenceSpec(scene="wall", frames=3, seed=3, width=160, height=120, hand_free_frames=1, lighting="step")
    frames = list(seq)
    for (state, pair, row), f in zip(generate(spec), frames):
        assert f.t == row["t"] and f.index == row["index"]
        np.testing.assert_array_equal(f.left, pair.left)
        np.testing.assert_array_equal(f.right, pair.right)
        np.testing.assert_array_equal(f.labels_left, pair.labels_left)
        np.testing.assert_array_equal(f.labels_right, pair.labels_right)
        np.testing.assert_allclose(gt["tip_cam"][f.index], row["tip_cam"])
    assert seq[-1].index == 2
    with pytest.raises(IndexError):
        seq[3]


@pytest.mark.render
def test_the_exposure_is_a_camera_setting_recorded_with_the_sequence(tmp_path):
    assert main(ARGS + ["--exposure-ms", "4", "--out", str(tmp_path / "short")]) == 0
    assert float(SyntheticSequence(tmp_path / "short").gt["exposure_s"]) == pytest.approx(0.004)


@pytest.mark.parametrize("args,match", [
    (["--scene", "moon"], "unknown scene"),
    (["--frames", "-2"], "frames"),
    (["--frames", "0"], "frames"),
    (["--background", "plaid"], "unknown background"),
    (["--skin-tone", "green"], "unknown skin tone"),
    (["--exposure-ms", "0"], "exposure"),
    (["--exposure-ms", "50"], "longer than a frame"),
    (["--exposure-ms", "4", "--no-effects"], "needs the camera effects"),
])
def test_bad_input_gives_one_error_and_writes_nothing(tmp_path, capsys, args, match):
    base = ["synth", "--scene", "wall", "--frames", "3", "--resolution", "160x120", "--quiet"]
    out = tmp_path / "deep" / "seq"
    argv = base + args + ["--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("vishap synth: error:") and match in err and len(err.splitlines()) == 1
    assert _leftovers(tmp_path) == []


def test_bad_rig_file(tmp_path, capsys):
    rig = tmp_path / "rig.yaml"
    rig.write_text("%YAML:1.0\n---\nimage_width: 640\n")
    out = tmp_path / "seq"
    assert main(ARGS + ["--rig", str(rig), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "rig.yaml" in err and len(err.strip().splitlines()) == 1
    assert _leftovers(tmp_path) == ["rig.yaml"]


def test_unwritable_output(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(ARGS + ["--out", str(blocker / "seq")]) == 2
    assert "cannot write" in capsys.readouterr().err
    assert main(ARGS + ["--out", str(blocker)]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert _leftovers(tmp_path) == ["file"]


def test_existing_output_is_kept_without_overwrite(tmp_path, capsys):
    out = tmp_path / "seq"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(ARGS + ["--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert _leftovers(out) == ["keep.txt"] and _leftovers(tmp_path) == ["seq"]


@pytest.mark.render
def test_failure_while_rendering_leaves_nothing(tmp_path, monkeypatch):
    import vishap.sim.writer as w

    def boom(*a, **k):
        raise RuntimeError("renderer crashed")

    real = w.render_frames

    def failing(p, r):
        for i, item in enumerate(real(p, r)):
            if i == 1:
                boom()
            yield item

    monkeypatch.setattr(w, "render_frames", failing)
    with pytest.raises(RuntimeError):
        write_sequence(tmp_path / "x" / "seq", SequenceSpec(scene="wall", frames=3, width=160, height=120))
    assert _leftovers(tmp_path) == []


def test_reader_errors(tmp_path):
    from vishap._core.errors import VisionError

    with pytest.raises(VisionError, match="not found"):
        SyntheticSequence(tmp_path / "none")
    with pytest.raises(VisionError, match="no rig.yaml"):
        SyntheticSequence(tmp_path)
    with pytest.raises(ConfigError):
        SequenceSpec(scene="wall", frames=2, msaa=3).validate()


# -- compact storage: the image streams as lossless FFV1 videos (issue 18, item 4) ---------------------
VIDEO = ["--fps", "10", "--frames", "18"]  # 10 hand-free frames to learn the background, then the hand enters


@pytest.fixture(scope="module")
def png_and_video(tmp_path_factory):
    """The same sequence stored both ways (camera effects on)."""
    base = tmp_path_factory.mktemp("stores")
    common = ["synth", "--scene", "wall", "--seed", "3", "--resolution", "160x120", "--quiet", *VIDEO]
    assert main([*common, "--out", str(base / "png")]) == 0
    assert main([*common, "--store", "video", "--out", str(base / "video")]) == 0
    return base / "png", base / "video"


@pytest.mark.render
def test_video_store_reads_back_bit_exact_in_any_order(png_and_video, tmp_path):
    from vishap.vision.evaluate import open_sequence

    png, video = png_and_video
    names = set(_digest(video))
    assert names == {"rig.yaml", "gt.npz", "frames.json", "left.mkv", "right.mkv", "labels/left.mkv", "labels/right.mkv"}
    assert _digest(video)["gt.npz"] == _digest(png)["gt.npz"]
    a, b, c = SyntheticSequence(png), SyntheticSequence(video), open_sequence(video)
    assert len(a) == len(b) == len(c) == 18
    assert (b[17].labels_left == 1).any()  # the hand is in view: a real test of the labels
    for i in (*range(18), 5, 4, 4, 17, 0):  # forwards, jumps back (the decoder reopens) and on, a frame twice
        fa, fb, fc = a[i], b[i], c[i]
        assert fb.t == fa.t and fc.t == fa.t
        for k in ("left", "right", "labels_left", "labels_right"):
            ref = getattr(fa, k)
            for got in (getattr(fb, k), getattr(fc, k)):
                assert got.dtype == ref.dtype and got.shape == ref.shape and np.array_equal(got, ref), (i, k)
    # deterministic bytes: the same arguments write the same videos
    again = tmp_path / "again"
    assert main(["synth", "--scene", "wall", "--seed", "3", "--resolution", "160x120", "--quiet", *VIDEO,
                 "--store", "video", "--out", str(again)]) == 0
    assert _digest(again) == _digest(video)


@pytest.mark.render
def test_track_and_eval_read_a_video_store_as_they_read_pngs(png_and_video, tmp_path, capsys):
    import json

    png, video = png_and_video

    def timeless(d):
        if isinstance(d, dict):
            return {k: timeless(v) for k, v in d.items() if not (k.endswith("_ms") or k.startswith("ms_") or k == "folder")}
        if isinstance(d, list):
            return [timeless(v) for v in d]
        return d

    tracks = []
    for src in (png, video):
        out = tmp_path / f"{src.name}.json"
        assert main(["track", str(src), "--out", str(out)]) == 0
        rec = json.loads(out.read_text())
        rec.pop("source")
        tracks.append(timeless(rec))
    assert tracks[0]["frames"] == 18 and tracks[0]["found"] > 0
    assert tracks[0] == tracks[1]
    capsys.readouterr()
    evals = []
    for src in (png, video):
        assert main(["eval", "vision", str(src), "--json"]) == 0
        evals.append(timeless(json.loads(capsys.readouterr().out)))
    assert evals[0]["frames"] == 18 and evals[0]["detection_rate"] > 0 and evals[0] == evals[1]


@pytest.mark.render
def test_damaged_video_store_is_one_clear_error(png_and_video, tmp_path):
    import shutil

    from vishap._core.errors import VisionError

    _, video = png_and_video
    bad = tmp_path / "bad"
    shutil.copytree(video, bad)
    (bad / "right.mkv").unlink()
    seq = SyntheticSequence(bad)
    with pytest.raises(VisionError, match="right.mkv: missing video"):
        seq[0]
    (bad / "frames.json").write_text("{}")
    with pytest.raises(VisionError, match="frames.json"):
        SyntheticSequence(bad)
    with pytest.raises(ConfigError, match="unknown store"):
        SequenceSpec(scene="wall", frames=2, store="zip").validate()
