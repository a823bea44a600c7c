import cv2
import numpy as np
import pytest

from vishap import ConfigError
from vishap.vision.rig import StereoRig


def _points(rng, n=200):
    # a working volume in front of the rig: 0.3–1.0 m deep, inside both fields of view
    z = rng.uniform(0.3, 1.0, n)
    x = rng.uniform(-0.25, 0.25, n) * z
    y = rng.uniform(-0.2, 0.2, n) * z
    return np.column_stack([x, y, z])


@pytest.mark.parametrize("rig_name", ["ideal_rig", "distorted_rig"])
def test_project_then_triangulate_recovers_points(rig_name, request, rng):
    rig = request.getfixturevalue(rig_name)
    p = _points(rng)
    uv_l, uv_r = rig.project(p)
    p_back = rig.triangulate(uv_l, uv_r)
    assert np.max(np.abs(p_back - p)) < 1e-9


def test_projection_agrees_with_opencv(distorted_rig, rng):
    p = _points(rng, 50)
    uv_l, uv_r = distorted_rig.project(p)
    ref_l, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), distorted_rig.K_left, distorted_rig.dist_left)
    rvec, _ = cv2.Rodrigues(distorted_rig.R)
    ref_r, _ = cv2.projectPoints(p, rvec, distorted_rig.T, distorted_rig.K_right, distorted_rig.dist_right)
    assert np.allclose(uv_l, ref_l.reshape(-1, 2), atol=1e-9)
    assert np.allclose(uv_r, ref_r.reshape(-1, 2), atol=1e-9)


def test_points_behind_camera_give_nan(ideal_rig):
    uv_l, uv_r = ideal_rig.project([[0.0, 0.0, -0.5]])
    assert np.all(np.isnan(uv_l)) and np.all(np.isnan(uv_r))


@pytest.mark.parametrize("rig_name", ["ideal_rig", "distorted_rig"])
def test_rectified_rows_agree_and_triangulate(rig_name, request, rng):
    rig = request.getfixturevalue(rig_name)
    p = _points(rng, 100)
    uv_l, uv_r = rig.project(p)
    rl = rig.rectify_points(uv_l, "left")
    rr = rig.rectify_points(uv_r, "right")
    assert np.max(np.abs(rl[:, 1] - rr[:, 1])) < 1e-6  # same row after rectification
    assert np.max(np.abs(rig.triangulate_rectified(rl, rr) - p)) < 1e-7


def test_rectification_maps_warp_image(ideal_rig):
    img = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    out = ideal_rig.rectify_image(img, "left")
    assert out.shape == img.shape
    # an ideal parallel rig rectifies to itself
    assert np.mean(np.abs(out[10:-10, 10:-10].astype(int) - img[10:-10, 10:-10])) < 1.0


@pytest.mark.parametrize("rig_name", ["ideal_rig", "distorted_rig"])
def test_save_load_is_exact(rig_name, request, tmp_path):
    rig = request.getfixturevalue(rig_name)
    path = rig.save(tmp_path / "rig.yaml")
    back = StereoRig.load(path)
    assert back.equals(rig)
    # and the file is what cv2.FileStorage reads
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert np.array_equal(fs.getNode("K1").mat(), rig.K_left)
    assert int(fs.getNode("image_width").real()) == 640
    fs.release()


def test_summary(ideal_rig):
    s = ideal_rig.summary()
    assert s["baseline_m"] == pytest.approx(0.06)
    assert s["hfov_deg"] == pytest.approx(60.0)
    assert s["image_size"] == [640, 480]


# ---------------------------------------------------------------- bad input
def _write_and_edit(rig, tmp_path, edit):
    text = rig.to_filestorage_string()
    path = tmp_path / "rig.yaml"
    path.write_text(edit(text))
    return path


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="rig.yaml.*not found"):
        StereoRig.load(tmp_path / "rig.yaml")


def test_truncated_file(ideal_rig, tmp_path):
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: t[: len(t) // 2])
    before = sorted(tmp_path.iterdir())
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert "rig.yaml" in str(exc.value)
    assert sorted(tmp_path.iterdir()) == before  # nothing else written


def test_missing_field_is_named(ideal_rig, tmp_path):
    import re

    path = _write_and_edit(ideal_rig, tmp_path, lambda t: re.sub(r"K2: !!opencv-matrix.*?\]\n", "", t, flags=re.S))
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert exc.value.field == "K2" and "missing" in str(exc.value) and "rig.yaml" in str(exc.value)


def test_wrong_type_field_is_named(ideal_rig, tmp_path):
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: t.replace("image_width: 640", 'image_width: "wide"'))
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert exc.value.field == "image_width"


def test_wrong_shape_field_is_named(ideal_rig, tmp_path):
    import re

    bad = "T: !!opencv-matrix\n   rows: 2\n   cols: 1\n   dt: d\n   data: [ -0.06, 0. ]\n"
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: re.sub(r"T: !!opencv-matrix.*?\]\n", bad, t, flags=re.S))
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert exc.value.field == "T"


def test_non_rotation_is_refused(ideal_rig, tmp_path):
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: t.replace("data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]", "data: [ 2., 0., 0., 0., 1., 0., 0., 0., 1. ]", 1))
    # the first identity block is R (K's come first and are not identities)
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert exc.value.field == "R"


def test_not_a_filestorage_file(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("hello: world\n")
    with pytest.raises(ConfigError, match="FileStorage"):
        StereoRig.load(path)


def test_bad_constructor_values():
    with pytest.raises(ConfigError):
        StereoRig.from_fov(baseline_m=0.0)
    with pytest.raises(ConfigError):
        StereoRig.from_fov(hfov_deg=200.0)


def test_save_is_atomic(ideal_rig, tmp_path, monkeypatch):
    target = tmp_path / "rig.yaml"
    target.write_text("old")
    monkeypatch.setattr(StereoRig, "to_filestorage_string", lambda self: (_ for _ in ()).throw(RuntimeError("boom")))
    with pytest.raises(RuntimeError):
        ideal_rig.save(target)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["rig.yaml"]
