"""vishap eval fingertip: labels, sources, scores, errors, outputs; the mono geometric detector."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from vishap._core.errors import ConfigError, VisionError
from vishap.cli import main
from vishap.vision.detector import MonoDetection, detector_names, make_detector
from vishap.vision.fingertip_eval import evaluate_fingertip, read_fingertip_labels, score_fingertips

SKIN = (90, 130, 200)      # BGR, OpenCV hue 11, saturation 140
PALE = (200, 215, 235)     # pale, brightly lit skin: hue 13, saturation 38 (under the paper's gate of 40)
GRASS = (40, 140, 40)


def hand_image(tip_uv, rng, *, pale_tip=False, finger_r=14, size=(640, 480), bg=GRASS):
    """A pointing hand entering from the bottom edge: palm, one finger up to ``tip_uv`` (its cap
    centre), optionally a pale cap; returns the image and the cap centre."""
    w, h = size
    img = np.empty((h, w, 3), np.uint8)
    img[:] = bg
    img = cv2.add(img, rng.integers(0, 12, img.shape, dtype=np.uint8))
    u, v = int(tip_uv[0]), int(tip_uv[1])
    cv2.rectangle(img, (u - 70, v + 120), (u + 50, h), SKIN, -1)            # palm to the bottom edge
    cv2.rectangle(img, (u - finger_r, v), (u + finger_r, v + 130), SKIN, -1)  # finger
    cv2.circle(img, (u, v), finger_r, PALE if pale_tip else SKIN, -1)        # cap
    if pale_tip:
        cv2.rectangle(img, (u - finger_r, v), (u + finger_r, v + finger_r), PALE, -1)
    return img


@pytest.fixture
def photo_folder(tmp_path, rng):
    d = tmp_path / "photos"
    d.mkdir()
    tips = {"a.png": (300, 150), "b.png": (250, 180), "c.png": (380, 140)}
    for name, uv in tips.items():
        cv2.imwrite(str(d / name), hand_image(uv, rng))
    lab = tmp_path / "labels.csv"
    lab.write_text("frame,u,v,extra\n" + "".join(f"{n},{u},{v},x\n" for n, (u, v) in tips.items()))
    return d, lab, tips


def test_registry_lists_the_geometric_variants():
    names = detector_names()
    assert {"paper", "geometric"} <= set(names)
    with pytest.raises(ConfigError, match="unknown"):
        make_detector("no-such-detector")


def test_scores_count_misses_as_failures():
    rec = score_fingertips([5.0, 15.0, 25.0, None, 40.0], [True, False])
    assert rec["frames"] == 5
    assert rec["detection_rate"] == pytest.approx(0.8)
    assert (rec["pck_10"], rec["pck_20"], rec["pck_30"]) == pytest.approx((0.2, 0.4, 0.6))
    assert rec["median_error_px"] == pytest.approx(20.0)
    assert rec["false_detections"] == 1 and rec["hidden_frames"] == 2


@pytest.mark.parametrize("name", ["geometric", "paper"])
def test_detectors_find_the_tip_of_a_clean_hand(photo_folder, name):
    d, lab, tips = photo_folder
    rec, rows = evaluate_fingertip(d, lab, make_detector(name))
    assert rec["frames"] == 3 and rec["detector"] == name
    assert rec["pck_10"] == 1.0, rows
    for r in rows:
        assert r["cap_u"] is not None


def test_geometric_keeps_a_pale_tip_the_paper_loses(tmp_path, rng):
    d = tmp_path / "p"
    d.mkdir()
    cv2.imwrite(str(d / "x.png"), hand_image((320, 120), rng, pale_tip=True))
    lab = tmp_path / "l.csv"
    lab.write_text("frame,u,v\nx.png,320,120\n")
    geo, _ = evaluate_fingertip(d, lab, make_detector("geometric"))
    paper, prow = evaluate_fingertip(d, lab, make_detector("paper"))
    assert geo["pck_10"] == 1.0
    assert paper["pck_10"] == 0.0, prow  # the pale cap falls under the saturation gate


class FixedDetector:
    name = "fixed"

    def __init__(self, uv):
        self.uv, self.resets = np.asarray(uv, float), 0

    def reset(self):
        self.resets += 1

    def process(self, image, t):
        return MonoDetection(t, True, tip_end_uv=self.uv.copy())


def test_photos_are_independent_and_hidden_frames_counted(photo_folder):
    d, lab, tips = photo_folder
    lab.write_text("frame,u,v\na.png,300,150\nb.png,,\nc.png,320,150\n")
    det = FixedDetector((300, 160))
    rec, rows = evaluate_fingertip(d, lab, det)
    assert det.resets >= 3  # reset before each photo
    assert rec["frames"] == 2 and rec["hidden_frames"] == 1 and rec["false_detections"] == 1
    assert rec["pck_10"] == 0.5 and rec["pck_30"] == 1.0


def _write_video(path, frames):
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (frames[0].shape[1], frames[0].shape[0]))
    assert vw.isOpened()
    for f in frames:
        vw.write(f)
    vw.release()


def test_video_by_index_tracks_and_left_of_a_pair(tmp_path, rng):
    tips = [(300 + 3 * i, 150 + i) for i in range(8)]
    frames = [hand_image(uv, rng) for uv in tips]
    vid = tmp_path / "v.avi"
    _write_video(vid, frames)
    lab = tmp_path / "l.csv"
    lab.write_text("frame,u,v\n" + "".join(f"{i},{u},{v}\n" for i, (u, v) in enumerate(tips) if i % 2 == 0))
    rec, rows = evaluate_fingertip(vid, lab, make_detector("geometric"))
    assert rec["frames"] == 4 and rec["pck_10"] == 1.0
    assert any(r["mode"].startswith("tracked") for r in rows)  # a sequence: the Kalman window is used
    rec2, _ = evaluate_fingertip(f"{vid},{vid}", lab, make_detector("geometric"))
    assert rec2["frames"] == 4 and rec2["pck_10"] == 1.0
    lab.write_text("frame,u,v\n0,300,150\n99,1,1\n")
    with pytest.raises(ConfigError, match=r"row 3: frame '99' does not exist"):
        evaluate_fingertip(vid, lab, make_detector("geometric"))


def test_bad_input_names_file_and_row(photo_folder, tmp_path):
    d, lab, _ = photo_folder
    bad = tmp_path / "bad.csv"
    bad.write_text("frame,x,v\na.png,1,2\n")
    with pytest.raises(ConfigError, match="bad.csv.*missing column.*u"):
        read_fingertip_labels(bad)
    bad.write_text("frame,u,v\na.png,1,2\nb.png,one,2\n")
    with pytest.raises(ConfigError, match="row 3"):
        read_fingertip_labels(bad)
    bad.write_text("frame,u,v\na.png,1,2\nzz.png,1,2\n")
    with pytest.raises(ConfigError, match="row 3: frame 'zz.png' does not exist"):
        evaluate_fingertip(d, bad, make_detector("paper"))
    (d / "broken.png").write_bytes(b"not a png")
    bad.write_text("frame,u,v\nbroken.png,1,2\n")
    with pytest.raises(VisionError, match="broken.png"):
        evaluate_fingertip(d, bad, make_detector("paper"))
    with pytest.raises(VisionError, match="not found"):
        evaluate_fingertip(tmp_path / "missing.mp4", lab, make_detector("paper"))


def test_cli_json_and_outputs_never_overwrite(photo_folder, tmp_path, capsys):
    d, lab, _ = photo_folder
    out = tmp_path / "res"
    assert main(["eval", "fingertip", str(d), "--labels", str(lab), "--detector", "paper", "--out", str(out), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    for k in ("frames", "detection_rate", "pck_10", "pck_20", "pck_30", "median_error_px", "ms_per_frame", "detector"):
        assert k in rec
    assert (out / "frames.csv").read_text().count("\n") == 4
    assert len(list((out / "worst").glob("*.png"))) == 3
    before = (out / "frames.csv").read_text()
    assert main(["eval", "fingertip", str(d), "--labels", str(lab), "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert (out / "frames.csv").read_text() == before


def test_no_visible_tip_gives_undefined_rates_not_zero():
    rec = score_fingertips([], [True, False])
    assert rec["detection_rate"] is None and rec["pck_30"] is None and rec["median_error_px"] is None
    assert rec["hidden_frames"] == 2 and rec["false_detections"] == 1

