import json

import cv2
import numpy as np
import pytest

from vishap.cli import main
from vishap.vision.evaluate import SequenceReader, evaluate_sequence, fit_skin_model, segmentation_ratios
from vishap.vision.rig import StereoRig
from vishap.vision.toy import ToyScene


def test_segmentation_ratios_count_pixels():
    mask = np.array([[255, 0], [255, 0]], np.uint8)
    labels = np.array([[1, 1], [0, 2]], np.uint8)
    assert segmentation_ratios(mask, labels).tolist() == [2, 1, 1, 4]


def _write_toy_sequence(folder, seed, n=16, learn=4):
    """A labelled sequence in the folder layout 'vishap synth' writes."""
    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    scene = ToyScene(rig, seed=seed)
    for d in ("left", "right", "labels/left", "labels/right"):
        (folder / d).mkdir(parents=True)
    rig.save(folder / "rig.yaml")
    gt = {k: [] for k in ("t", "tip_cam", "tip_uv_left", "tip_uv_right", "tip_visible_left", "tip_visible_right")}
    for i in range(n):
        p = np.array([-0.03 + 0.003 * i, 0.005 * i, 0.45])
        f = scene.frame(i / 30, p, hand=i >= learn)
        name = f"{i:06d}.png"
        for sub, img in (("left", f.left), ("right", f.right), ("labels/left", f.labels_left), ("labels/right", f.labels_right)):
            cv2.imwrite(str(folder / sub / name), img)
        for k, v in (("t", i / 30), ("tip_cam", p), ("tip_uv_left", f.tip_uv_left), ("tip_uv_right", f.tip_uv_right),
                     ("tip_visible_left", i >= learn), ("tip_visible_right", i >= learn)):
            gt[k].append(v)
    np.savez(folder / "gt.npz", **{k: np.array(v) for k, v in gt.items()})


@pytest.fixture(scope="module")
def toy_sequences(tmp_path_factory):
    root = tmp_path_factory.mktemp("seq")
    for s in (1, 2):
        _write_toy_sequence(root / f"s{s}", seed=s)
    return root


def test_evaluate_a_toy_sequence(toy_sequences):
    skin = fit_skin_model([toy_sequences / "s2"])  # fitted on another sequence than the evaluated one
    seq = SequenceReader(toy_sequences / "s1")
    assert len(seq) == 16 and seq[5].labels_left.dtype == np.uint8
    from vishap.vision.pipeline import PipelineConfig

    res = evaluate_sequence(toy_sequences / "s1", skin_model=skin, config=PipelineConfig(learn_frames=4))
    assert res["seg_correct"] > 0.995 and res["seg_false_positive"] < 0.005 and res["seg_false_negative"] < 0.005
    assert res["visible_frames"] == 12 and res["detection_rate"] > 0.9
    assert res["tip2d_rms_px"] < 0.6 and res["tip3d_rms_mm"] < 5.0
    assert res["ms_per_pair"] > 0 and res["track_losses"] == 0


def test_cli_track_eval_and_skin(toy_sequences, tmp_path, capsys):
    assert main(["skin", "fit", str(toy_sequences / "s2"), "--out", str(tmp_path / "skin.yaml")]) == 0
    capsys.readouterr()
    assert main(["track", str(toy_sequences / "s1"), "--out", str(tmp_path / "tracks.json"),
                 "--skin", str(tmp_path / "skin.yaml")]) == 0
    rec = json.loads((tmp_path / "tracks.json").read_text())
    assert rec["frames"] == 16 and len(rec["tracks"]) == 16
    row = rec["tracks"][-1]
    assert set(row) >= {"t", "tip_uv_left", "tip_uv_right", "tip_cam", "confidence", "timing_ms"}
    capsys.readouterr()
    assert main(["eval", "vision", str(toy_sequences / "s1"), "--skin", str(tmp_path / "skin.yaml")]) == 0
    out = json.loads(capsys.readouterr().out)
    for k in ("seg_correct", "seg_false_positive", "seg_false_negative", "tip2d_rms_px", "tip3d_rms_mm",
              "detection_rate", "ms_per_pair"):
        assert out[k] is not None
    assert main(["track", str(tmp_path / "missing"), "--out", str(tmp_path / "x.json")]) == 2
