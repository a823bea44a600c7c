"""The committed sample (datasets/synthetic/sample) is a valid sequence with consistent ground truth (no rendering)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vishap._core.pose import transform_points
from vishap.sim.reader import SyntheticSequence
from vishap.sim.trajectory import PHASES

SAMPLE = Path(__file__).resolve().parents[2] / "datasets" / "synthetic" / "sample"


def test_sample_is_small_and_consistent():
    size = sum(p.stat().st_size for p in SAMPLE.rglob("*") if p.is_file())
    assert size < 700_000
    seq = SyntheticSequence(SAMPLE)
    gt = seq.gt
    assert len(seq) >= 5 and str(gt["scene"]) == "wall"
    assert list(gt["phase_names"]) == list(PHASES)
    np.testing.assert_allclose(transform_points(seq.T_robot_cam, gt["tip_cam"]), gt["tip_robot"], atol=1e-12)
    n_vis = 0
    for f in seq:
        uvl, uvr = seq.rig.project(gt["tip_cam"][f.index])
        assert np.abs(uvl[0] - gt["tip_uv_left"][f.index]).max() < 0.01
        assert np.abs(uvr[0] - gt["tip_uv_right"][f.index]).max() < 0.01
        assert f.left.shape == (120, 160, 3) and f.labels_left.shape == (120, 160)
        assert set(np.unique(f.labels_left)) <= {0, 1, 2, 3}
        for side in ("left", "right"):
            if gt[f"tip_visible_{side}"][f.index]:
                n_vis += 1
                u, v = (int(np.floor(c + 0.5)) for c in gt[f"tip_uv_{side}"][f.index])
                assert getattr(f, f"labels_{side}")[v, u] == 1
    assert n_vis >= 6
    hf = int(gt["hand_free_frames"])
    assert not gt["hand_visible"][:hf].any() and gt["hand_visible"][hf:].all()
    assert gt["in_contact"].any()
    c = gt["contact_robot"][gt["in_contact"]]
    np.testing.assert_allclose(c[:, 2], -0.150, atol=1e-9)
