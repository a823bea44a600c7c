import numpy as np
import pytest

from vishap import ShapeError
from vishap.vision.capture import StereoFrame
from vishap.vision.pipeline import PipelineConfig, VisionPipeline
from vishap.vision.rig import StereoRig
from vishap.vision.skin_model import SkinModel
from vishap.vision.toy import ToyScene


@pytest.fixture(scope="module")
def setup():
    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    train = ToyScene(rig, seed=11)  # skin model from another "seed" than the evaluated one
    fr = [train.frame(0, (0.0, 0.0, 0.45))]
    skin = SkinModel.fit([f.left for f in fr], [f.labels_left for f in fr])
    return rig, skin


def _traj(k):
    return np.array([-0.04 + 0.002 * k, 0.01 * np.sin(k / 6), 0.42 + 0.001 * k])


def test_tracks_a_toy_finger_and_recovers_after_it_leaves(setup):
    rig, skin = setup
    scene = ToyScene(rig, seed=5)
    pipe = VisionPipeline(rig, skin_model=skin, config=PipelineConfig(learn_frames=4))
    k = 0
    for i in range(4):  # automatic background learning on the first frames
        est = pipe.process(StereoFrame(i, i / 30, *_pair(scene.frame(i / 30, _traj(0), hand=False))))
        assert est.mode == "learning" and not est.found
    errs2, errs3, modes = [], [], []
    for i in range(4, 40):
        t = i / 30
        hand = not (20 <= i < 28)  # the finger leaves the view for 8 frames, then comes back
        f = scene.frame(t, _traj(i), light=1.0 - 0.004 * i, hand=hand)
        est = pipe.process(StereoFrame(i, t, f.left, f.right))
        modes.append(est.mode)
        if not hand:
            assert not est.found
            continue
        if i >= 29:  # recovered
            assert est.found, (i, est.reason)
        if est.found:
            errs2.append(np.r_[est.uv_left - f.tip_uv_left, est.uv_right - f.tip_uv_right])
            errs3.append(est.p_cam - f.tip_cam)
            assert est.cov_cam.shape == (3, 3) and 0 < est.confidence <= 1
    assert "tracked" in modes and modes.count("full") >= 2
    rms2 = np.sqrt(np.mean(np.square(errs2)))
    rms3 = np.sqrt(np.mean(np.sum(np.square(errs3), axis=1)))
    assert len(errs2) >= 26 and rms2 < 0.5 and rms3 < 0.004


def _pair(f):
    return f.left, f.right


def test_bad_frames_give_clear_errors(setup):
    rig, skin = setup
    pipe = VisionPipeline(rig, skin_model=skin)
    with pytest.raises(ShapeError, match="left image: expected 320×240"):
        pipe.process(StereoFrame(0, 0.0, np.zeros((10, 10, 3), np.uint8), np.zeros((240, 320, 3), np.uint8)))
    with pytest.raises(ShapeError, match="right image: expected uint8"):
        pipe.process(StereoFrame(0, 0.0, np.zeros((240, 320, 3), np.uint8), np.zeros((240, 320), np.uint8)))
