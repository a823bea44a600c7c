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


# ---------------------------------------------------------------- hostile files (issue 17)
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402


def _replace_node(text: str, name: str, body: str) -> str:
    return re.sub(rf"^{name}: !!opencv-matrix.*?\]\n", f"{name}: {body}\n", text, count=1, flags=re.S | re.M)


_NO_COLS = "!!opencv-matrix\n   rows: 3\n   dt: d\n   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]"
_ROWS_TWICE = "!!opencv-matrix\n   rows: 3\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]"


@pytest.mark.parametrize("body, what", [(_NO_COLS, "field 'R': !!opencv-matrix lacks 'cols:'"),
                                        (_ROWS_TWICE, "'rows' is given twice line 30")])
def test_malformed_matrix_node_never_crashes_the_interpreter(ideal_rig, tmp_path, body, what):
    """cv2's reader corrupted memory on these (SIGSEGV/SIGABRT about 1 run in 5): load 20 times in
    a child process, which must survive, and each load must be one ConfigError naming the node."""
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: _replace_node(t, "R", body))
    code = ("import sys\nfrom vishap import ConfigError\nfrom vishap.vision.rig import StereoRig\n"
            "for _ in range(20):\n    try:\n        StereoRig.load(sys.argv[1])\n        raise SystemExit('accepted')\n"
            "    except ConfigError as e:\n        msg = str(e)\nprint(msg)\n")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, (out.returncode, out.stderr[-500:])
    assert what in out.stdout and "rig.yaml" in out.stdout


@pytest.mark.parametrize("junk", ["\x07junk", ": : :", "abc", "[1,2", "K1: !!opencv-matrix\n  rows: 3\n junk ]]]"])
def test_junk_after_the_header_is_a_config_error(tmp_path, junk):
    path = tmp_path / "rig.yaml"
    path.write_text(f"%YAML:1.0\n---\n{junk}\n")
    with pytest.raises(ConfigError, match="rig.yaml"):
        StereoRig.load(path)


def _scale_matrix_value(text, name, index, value):
    m = re.search(rf"^{name}: !!opencv-matrix.*?data: \[(.*?)\]", text, flags=re.S | re.M)
    vals = [v.strip() for v in m.group(1).split(",")]
    vals[index] = value
    return text[: m.start(1)] + " " + ", ".join(vals) + " " + text[m.end(1):]


@pytest.mark.parametrize(
    "name, index, value, field",
    [
        ("K1", 0, "1e300", "K1"),  # a 1e300 px focal length
        ("K2", 4, "1e-300", "K2"),
        ("K1", 2, "1e12", "K1"),  # principal point far outside the image
        ("D1", 0, "1e200", "D1"),
        ("T", 0, "-60.0", "T"),  # millimetres, not metres
        ("R1", 1, "0.2", "R1"),  # a skewed R1: no longer a rotation
        ("Q", 11, ".nan", "Q"),
        ("P2", 0, "1e300", "P2"),
    ],
)
def test_out_of_range_values_are_refused_with_the_field(ideal_rig, tmp_path, name, index, value, field):
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: _scale_matrix_value(t, name, index, value))
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert exc.value.field.split(".")[0] == field and "rig.yaml" in str(exc.value)


def test_rectification_that_does_not_belong_to_the_rig_is_refused(distorted_rig, tmp_path):
    from vishap._core.pose import rot_y

    def rotate_R1(t):  # still a proper rotation, but not the one rectifying these cameras
        R1 = rot_y(0.05) @ distorted_rig.R1
        body = "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ " + ", ".join(repr(float(x)) for x in R1.ravel()) + " ]"
        return _replace_node(t, "R1", body)

    path = _write_and_edit(distorted_rig, tmp_path, rotate_R1)
    with pytest.raises(ConfigError, match="R2·R") as exc:
        StereoRig.load(path)
    assert exc.value.field == "R1"
    zeros = "!!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ " + ", ".join(["0."] * 16) + " ]"
    path = _write_and_edit(distorted_rig, tmp_path, lambda t: _replace_node(t, "Q", zeros))
    with pytest.raises(ConfigError, match="P1 and P2") as exc:
        StereoRig.load(path)
    assert exc.value.field == "Q"


def test_file_carries_image_size_rms_and_board(distorted_rig, tmp_path):
    import stat

    rig = distorted_rig.with_calibration_info(rms_px=0.31, board="chessboard", board_size=(9, 6), square_m=0.025)
    path = rig.save(tmp_path / "rig.yaml")
    text = path.read_text()
    for node in ("image_size: [ 640, 480 ]", "rms_px: 0.31", "board: chessboard", "board_width: 9", "board_height: 6",
                 "square_size: 0.025"):
        assert node in text, node
    back = StereoRig.load(path)
    assert back.equals(rig) and back.rms_px == 0.31 and back.board == "chessboard"
    assert back.board_size == (9, 6) and back.square_m == 0.025
    assert not back.equals(rig.with_calibration_info(rms_px=0.31, board="chessboard", board_size=(9, 7), square_m=0.025))
    assert back.summary()["rms_px"] == 0.31 and back.summary()["square_m"] == 0.025
    assert stat.S_IMODE(path.stat().st_mode) & 0o040  # group-readable, not 0600


def _opencv_sample_files(rig) -> tuple[str, str]:
    """The two files OpenCV's stereo_calib sample writes (intrinsics.yml, extrinsics.yml)."""
    def mat(name, a):
        a = np.atleast_2d(a)
        return (f"{name}: !!opencv-matrix\n   rows: {a.shape[0]}\n   cols: {a.shape[1]}\n   dt: d\n   data: [ "
                + ", ".join(repr(float(x)) for x in a.ravel()) + " ]\n")

    intr = "%YAML:1.0\n---\n" + mat("M1", rig.K_left) + mat("D1", rig.dist_left) + mat("M2", rig.K_right) \
        + mat("D2", rig.dist_right)
    extr = "%YAML:1.0\n---\n" + "".join(mat(k, getattr(rig, k)) for k in ("R", "T", "R1", "R2", "P1", "P2", "Q"))
    return intr, extr


def test_opencv_sample_key_names_are_read(distorted_rig, tmp_path):
    intr, extr = _opencv_sample_files(distorted_rig)
    path = tmp_path / "rig.yml"
    path.write_text(intr + extr)  # the sample's two files, concatenated
    with pytest.raises(ConfigError, match="image_size.*stereo_calib") as exc:
        StereoRig.load(path)
    assert exc.value.field == "image_size"
    path.write_text(intr + "image_size: [ 640, 480 ]\n" + extr)
    back = StereoRig.load(path)
    assert back.equals(distorted_rig)
    path.write_text(intr.replace("M1:", "K1:") + intr.split("---\n")[1].split("D1:")[0] + extr
                    + "image_size: [ 640, 480 ]\n")
    with pytest.raises(ConfigError, match="twice|both"):
        StereoRig.load(path)


def test_unknown_node_and_xml_are_named(ideal_rig, tmp_path):
    path = _write_and_edit(ideal_rig, tmp_path, lambda t: t + "K_1: 3\n")
    with pytest.raises(ConfigError, match="unknown node") as exc:
        StereoRig.load(path)
    assert exc.value.field == "K_1"
    path.write_text('<?xml version="1.0"?>\n<opencv_storage></opencv_storage>\n')
    with pytest.raises(ConfigError, match="XML"):
        StereoRig.load(path)


@pytest.mark.parametrize("node, value, field", [
    ("rms_px", ".nan", "rms_px"), ("rms_px", "-1.", "rms_px"), ("rms_px", '"x"', "rms_px"),
    ("square_size", ".inf", "square_size"), ("square_size", "0.", "square_size"), ("square_size", "25.", "square_size"),
    ("board_width", "1", "board_width"), ("board_width", "1e300", "board_width"), ("board_width", "9.5", "board_width"),
    ("board_height", "100000", "board_height"), ("board_height", ".nan", "board_height"),
])
def test_calibration_info_out_of_range_is_refused_with_the_field(distorted_rig, tmp_path, node, value, field):
    rig = distorted_rig.with_calibration_info(rms_px=0.31, board="chessboard", board_size=(9, 6), square_m=0.025)
    path = _write_and_edit(rig, tmp_path, lambda t: re.sub(rf"^{node}: .*$", f"{node}: {value}", t, count=1, flags=re.M))
    with pytest.raises(ConfigError) as exc:
        StereoRig.load(path)
    assert exc.value.field == field and "rig.yaml" in str(exc.value)


def test_a_pattern_size_needs_both_sides(distorted_rig, tmp_path):
    rig = distorted_rig.with_calibration_info(board_size=(9, 6))
    path = _write_and_edit(rig, tmp_path, lambda t: re.sub(r"^board_height: .*\n", "", t, flags=re.M))
    with pytest.raises(ConfigError, match="board_width and board_height") as exc:
        StereoRig.load(path)
    assert exc.value.field == "board_height"


def _rotated_rig(skew: float = 0.0, distorted: bool = False) -> StereoRig:
    """A rig whose rectification rotates both views (toe-in and offset), optionally with skew or distortion."""
    from vishap._core.pose import rotvec_to_matrix

    K1 = np.array([[560.0, skew, 322.0], [0.0, 558.0, 241.5], [0.0, 0.0, 1.0]])
    K2 = np.array([[552.0, 0.0, 317.0], [0.0, 553.5, 238.0], [0.0, 0.0, 1.0]])
    d = np.array([-0.21, 0.08, 0.0012, -0.0007, -0.012]) if distorted else np.zeros(5)
    return StereoRig((640, 480), K1, d, K2, d.copy(), rotvec_to_matrix([0.004, -0.03, 0.002]),
                     np.array([-0.0601, 0.0007, 0.0012]))


@pytest.mark.parametrize("skew, distorted", [(0.0, False), (0.8, False), (0.0, True)])
def test_rectified_points_are_opencvs_floats(skew, distorted, rng):
    # one point in floats, a few (the pipeline's candidates), many (through OpenCV): the same floats
    rig = _rotated_rig(skew, distorted)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-14)
    for side, K, d, Rr, P in (("left", rig.K_left, rig.dist_left, rig.R1, rig.P1),
                              ("right", rig.K_right, rig.dist_right, rig.R2, rig.P2)):
        for n in (1, 3, 40):
            uv = rng.uniform([-20.0, -20.0], [660.0, 500.0], (n, 2))
            ref = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, d, None, Rr, P, crit).reshape(-1, 2)
            np.testing.assert_array_equal(rig.rectify_points_fast(uv, side), ref)
            np.testing.assert_array_equal([rig.rectify_point(u, v, side) for u, v in uv.tolist()], ref)


def test_assigning_a_field_drops_what_was_derived_from_it(rng):
    # the rig keeps each view's constants, its rectification maps and Q's rows until a field is assigned
    rig, other = _rotated_rig(), StereoRig.from_fov(640, 480, 70.0, 0.08)
    uv = rng.uniform([50.0, 50.0], [590.0, 430.0], (3, 2))
    before = {s: rig.rectify_points_fast(uv, s) for s in ("left", "right")}
    maps_before = rig.rectification_maps("left")[0].copy()
    assert rig.Q_rows == tuple(map(tuple, rig.Q.tolist()))
    for name in ("K_left", "dist_left", "K_right", "dist_right", "R", "T", "R1", "R2", "P1", "P2", "Q"):
        setattr(rig, name, getattr(other, name))
    for s in ("left", "right"):
        got = rig.rectify_points_fast(uv, s)
        assert not np.allclose(got, before[s])
        np.testing.assert_array_equal(got, other.rectify_points_fast(uv, s))
        np.testing.assert_array_equal(rig.rectify_point(*uv[0], s), other.rectify_point(*uv[0], s))
    assert not np.array_equal(rig.rectification_maps("left")[0], maps_before)
    np.testing.assert_array_equal(rig.rectification_maps("left")[0], other.rectification_maps("left")[0])
    assert rig.Q_rows == other.Q_rows
    assert (rig.rectified_fx_px, rig.rectified_baseline_m) == (other.rectified_fx_px, other.rectified_baseline_m)
