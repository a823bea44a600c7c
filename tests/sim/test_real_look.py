"""The real look (``skin_tone: real``) and real-photograph backgrounds (``background: photo``):
selectable, deterministic, wider skin statistics at the fingertip, exact labels; the plain look
(the default) unchanged."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.cli import main
from vishap.sim.hand import skin_tone_rgb
from vishap.sim.sequence import SequenceSpec, frame_state, generate, make_renderer, prepare
from vishap.sim.skin_look import parse_skin_tone
from vishap.sim.textures import PHOTOS, choose_background, make_texture

SAMPLE = Path(__file__).resolve().parents[2] / "datasets" / "synthetic" / "sample"


def test_skin_tone_specs():
    assert parse_skin_tone(None) == (False, None)
    assert parse_skin_tone("dark") == (False, "dark")
    assert parse_skin_tone(0.3) == (False, 0.3)
    assert parse_skin_tone("real") == (True, None)
    assert parse_skin_tone("real:dark") == (True, "dark")
    assert parse_skin_tone("real:0.25") == (True, 0.25)
    assert skin_tone_rgb("real:tan") == skin_tone_rgb("tan")
    for bad in ("purple", "real:purple", "realistic"):
        with pytest.raises(ConfigError, match="unknown skin tone"):
            parse_skin_tone(bad)


def test_photo_backgrounds(tmp_path):
    assert choose_background("photo", 3) == "photo:hopper" and "hopper" in PHOTOS
    a = make_texture("photo:hopper", np.random.default_rng(1), size=64)
    b = make_texture("photo:hopper", np.random.default_rng(1), size=64)
    c = make_texture("photo:hopper", np.random.default_rng(2), size=64)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (64, 64, 3) and a.dtype == np.uint8 and np.abs(a.astype(int) - c).mean() > 5
    # any image file; the texture is RGB (the file is read as BGR)
    f = tmp_path / "red.png"
    img = np.zeros((40, 60, 3), np.uint8)
    img[..., 2] = 200  # red in BGR
    cv2.imwrite(str(f), img)
    assert choose_background(f"photo:{f}", 0) == f"photo:{f}"
    t = make_texture(f"photo:{f}", np.random.default_rng(0), size=16)
    assert (t[..., 0] == 200).all() and not t[..., 1:].any()
    with pytest.raises(ConfigError, match="unknown photograph 'nope'"):
        choose_background("photo:nope", 0)
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"not an image")
    with pytest.raises(ConfigError, match="cannot read the photograph"):
        make_texture(f"photo:{bad}", np.random.default_rng(0))


@pytest.mark.render
def test_plain_look_still_renders_the_committed_sample():
    """The default look is untouched: the committed sample's pixels come out again."""
    spec = SequenceSpec(scene="wall", trajectory="short", frames=6, seed=0, width=160, height=120)
    for _, pair, row in generate(spec):
        i = row["index"]
        for side in ("left", "right"):
            ref = cv2.imread(str(SAMPLE / side / f"{i:06d}.png"), cv2.IMREAD_COLOR)
            diff = np.abs(ref.astype(int) - getattr(pair, side))
            assert (diff > 2).mean() < 1e-3, (side, i)
        lab = cv2.imread(str(SAMPLE / "labels" / "left" / f"{i:06d}.png"), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(lab, pair.labels_left)


def _one_frame(seed, skin_tone, background, t=2.5, effects=False, **kw):
    p = prepare(SequenceSpec(scene="wall", frames=1, seed=seed, width=160, height=120, skin_tone=skin_tone,
                             background=background, effects=effects, **kw))
    state, _ = frame_state(p, t)
    r = make_renderer(p)
    try:
        return r, r.render(state), r.render(state, labels="seg")
    finally:
        r.close()


@pytest.mark.render
def test_real_look_is_deterministic_and_keeps_exact_labels():
    r1, a, a_seg = _one_frame(5, "real", "photo")
    _, b, _ = _one_frame(5, "real", "photo")
    r3, c, _ = _one_frame(6, "real", "photo")
    _, plain, _ = _one_frame(5, None, "auto")
    np.testing.assert_array_equal(a.left, b.left)
    np.testing.assert_array_equal(a.right, b.right)
    assert r1.look.real and r1.background == "photo:hopper" and r1.look != r3.look
    assert np.abs(a.left.astype(int) - c.left).mean() > 3
    # the look changes the pixels, not the geometry: labels from alpha equal the flat pass and the
    # plain look's labels; depth is the same
    np.testing.assert_array_equal(a.labels_left, a_seg.labels_left)
    np.testing.assert_array_equal(a.labels_left, plain.labels_left)
    np.testing.assert_array_equal(a.depth_left, plain.depth_left)
    skin = a.labels_left == 1
    assert skin.sum() > 30 and np.abs(a.left[skin].astype(int) - plain.left[skin]).mean() > 5


@pytest.mark.render
def test_real_look_widens_the_fingertip_statistics():
    """What the real photos taught: pale (S < 40) and clipped (V >= 250) fingertip pixels, and a
    wider saturation range, none of which the plain look shows."""
    from vishap.bench.synth_appearance import render_tip_hsv

    px = {"real": [], None: []}
    for tone in px:
        for seed in range(6):
            spec = SequenceSpec(scene="wall", frames=2, seed=seed, width=320, height=240, skin_tone=tone,
                                start_s=1.0, fps=1.0, hand_free_frames=0)
            rig = prepare(spec).rig
            for _, pair, row in generate(spec):
                px[tone].append(render_tip_hsv(pair, row, rig))
    real, plain = np.concatenate(px["real"]), np.concatenate(px[None])
    assert len(real) > 200 and len(plain) > 200
    assert np.mean(real[:, 1] < 40) > 0.05 and np.mean(plain[:, 1] < 40) < 0.03
    assert np.mean(real[:, 2] >= 250) > np.mean(plain[:, 2] >= 250) + 0.02
    spread = {k: np.subtract(*np.percentile(v[:, 1], [95, 5])) for k, v in (("real", real), ("plain", plain))}
    assert spread["real"] > spread["plain"] + 40


def test_selectable_in_synth_and_dataset_specs(tmp_path, capsys):
    from vishap.scale.dataset_spec import load_dataset_spec

    f = tmp_path / "spec.yaml"
    f.write_text('groups:\n  - {name: real, scene: wall, seeds: "0:3", frames: 2, skin_tone: [real, "real:dark"], '
                 'background: photo}\n')
    _, jobs = load_dataset_spec(f)
    specs = [j.spec for j in jobs]
    assert [s.skin_tone for s in specs] == ["real", "real:dark", "real"]
    assert {s.background for s in specs} == {"photo"}
    f.write_text('groups:\n  - {name: real, scene: wall, seeds: "0:1", skin_tone: "real:purple"}\n')
    with pytest.raises(ConfigError, match="skin_tone"):
        load_dataset_spec(f)
    out = tmp_path / "seq"
    argv = ["synth", "--scene", "wall", "--frames", "2", "--resolution", "160x120", "--quiet", "--out", str(out)]
    assert main(argv + ["--background", "photo:nope"]) == 2
    assert "unknown photograph 'nope'" in capsys.readouterr().err and not out.exists()
