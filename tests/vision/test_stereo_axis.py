"""The finger's axis from its side edges (vishap.vision.axis_disparity) and the pair refinement
that averages its disparity with the cap fits' (RefineConfig(method="axis"))."""
import cv2
import numpy as np
import pytest

from vishap.vision.axis_disparity import axis_disparity, axis_line
from vishap.vision.fingertip import detect_fingertips

SS = 8  # supersampling of the drawn masks: a pixel is skin when over half of it is covered


def _finger_mask(centre, angle_deg, radius, size=(640, 480)):
    """A binary skin mask of a finger (a capsule 5 radii long behind its cap) with the cap centre
    at ``centre`` (float pixels) and the finger running at ``angle_deg`` from the image's +v axis."""
    w, h = size
    a = np.deg2rad(angle_deg)
    d = np.array([np.sin(a), np.cos(a)])
    c = np.asarray(centre, dtype=np.float64)
    q = lambda p: tuple(int(round(x)) for x in (p * SS + (SS - 1) / 2))  # pixel centre convention
    big = np.zeros((h * SS, w * SS), np.uint8)
    end = c + 5.0 * radius * d
    cv2.line(big, q(c), q(end), 255, thickness=int(round(2 * radius * SS)))
    cv2.circle(big, q(c), int(round(radius * SS)), 255, -1)
    cv2.circle(big, q(end), int(round(radius * SS)), 255, -1)
    cover = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)
    return ((cover >= 128) * 255).astype(np.uint8), d


def _tip(mask, radius, near):
    cands = detect_fingertips(mask, 0.6 * radius, max_tips=4)
    return min(cands, key=lambda t: np.hypot(*(t.uv - near)))


KW = dict(from_radii=0.1, to_radii=1.5, max_tilt_deg=60.0, width_tol=0.3, max_residual_px=0.75, min_points=4)


def test_axis_line_finds_the_axis_of_a_tilted_finger_to_a_fraction_of_the_cap_fit(ideal_rig, rng):
    """On binary masks of a finger tilted 15–40° from the columns, the fitted axis passes within a
    few hundredths of a pixel of the true one at the mean row of its edge points, where the cap
    circle's centre column is off by about a tenth: the side edges give several times the points.
    (Extrapolated to the cap centre's row the slope's error takes the gain back: the refinement
    uses the mean row.)"""
    ax_err, cap_err = [], []
    for k in range(16):
        c = np.array([300.0, 220.0]) + rng.uniform(0, 1, 2)
        ang = rng.uniform(15, 40) * (1 if k % 2 else -1)
        r = rng.uniform(7.0, 9.0)
        mask, d = _finger_mask(c, ang, r)
        tip = _tip(mask, r, c)
        line = axis_line(ideal_rig, "left", mask, (0, 0), tip, **KW)
        assert not isinstance(line, str), line
        assert abs(line.slope - d[0] / d[1]) < 0.06
        assert sum(line.points) >= 20
        ax_err.append(line.u_at(line.v_mean) - (c[0] + d[0] / d[1] * (line.v_mean - c[1])))
        cap_err.append(tip.uv[0] - c[0])
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))
    assert rms(ax_err) < 0.08 and rms(ax_err) < 0.7 * rms(cap_err), (rms(ax_err), rms(cap_err))


def test_axis_refinement_recovers_the_known_disparity(ideal_rig, rng):
    """A stereo pair of finger masks whose axes are ``disp`` apart along every rectified row: the
    axis's disparity at the mean row of its edge points is recovered to about a tenth of a pixel
    RMS, the refined pair's disparity is the mean of it and the cap fits', on one rectified row."""
    from vishap.vision.stereo import RefineConfig, refine_tip_pair

    err = []
    for k in range(8):
        cl = np.array([330.0, 230.0]) + rng.uniform(0, 1, 2)
        disp = 60.0 + rng.uniform(0, 1)
        ang, r = rng.uniform(15, 40), rng.uniform(7.0, 9.0)
        ml, _ = _finger_mask(cl, ang, r)
        mr, _ = _finger_mask(cl - (disp, 0.0), ang, r)
        tl, tr = _tip(ml, r, cl), _tip(mr, r, cl - (disp, 0.0))
        masks = {"left": (ml, (0, 0)), "right": (mr, (0, 0))}
        lines = [axis_line(ideal_rig, s, masks[s][0], (0, 0), t, **KW) for s, t in (("left", tl), ("right", tr))]
        axis = axis_disparity(*lines, 0.5 * (lines[0].v_mean + lines[1].v_mean))
        err.append(axis - disp)
        ref = refine_tip_pair(ideal_rig, None, None, tl, tr, RefineConfig(method="axis"), masks=masks)
        assert ref.ok, ref.reason
        got = ref.uv_left[0] - ref.uv_right[0]
        cap = tl.uv[0] - tr.uv[0]
        assert got == pytest.approx(0.5 * (axis + cap), abs=1e-6)
        assert abs(ref.uv_left[1] - ref.uv_right[1]) < 1e-9  # one rectified row
    assert np.sqrt(np.mean(np.square(err))) < 0.12, err


def test_axis_refinement_refuses_what_it_cannot_measure(ideal_rig):
    from vishap import VisionError
    from vishap.vision.fingertip import Fingertip
    from vishap.vision.stereo import RefineConfig, refine_tip_pair

    ml, _ = _finger_mask((330.4, 230.2), 80.0, 8.0)   # lying along the rows
    mr, _ = _finger_mask((270.1, 230.2), 80.0, 8.0)
    tl, tr = _tip(ml, 8.0, (330.4, 230.2)), _tip(mr, 8.0, (270.1, 230.2))
    masks = {"left": (ml, (0, 0)), "right": (mr, (0, 0))}
    ref = refine_tip_pair(ideal_rig, None, None, tl, tr, RefineConfig(method="axis"), masks=masks)
    assert not ref.ok and "rows" in ref.reason
    blob = np.zeros_like(ml)
    cv2.circle(blob, (330, 230), 8, 255, -1)  # a cap with no finger behind it
    tb = Fingertip(True, uv=np.array([330.0, 230.0]), direction=np.array([0.0, 1.0]), radius_px=5.0, cap_radius_px=8.0)
    ref = refine_tip_pair(ideal_rig, None, None, tb, tb, RefineConfig(method="axis"),
                          masks={"left": (blob, (0, 0)), "right": (blob, (0, 0))})
    assert not ref.ok and "sides end" in ref.reason
    with pytest.raises(VisionError, match="skin masks"):
        refine_tip_pair(ideal_rig, None, None, tl, tr, RefineConfig(method="axis"))


def test_the_pipeline_takes_the_disparity_from_the_side_edges_by_default(ideal_rig):
    """The default pipeline refines the chosen pair with the side-edge axis on its own skin masks
    (a toy finger, 640×480): the refinement succeeds on most tracked pairs and the 3-D tip stays
    on the truth; the masks of both views reach it."""
    from vishap.vision.capture import StereoFrame
    from vishap.vision.pipeline import PipelineConfig, VisionPipeline
    from vishap.vision.skin_model import SkinModel
    from vishap.vision.toy import ToyScene

    train = ToyScene(ideal_rig, seed=11).frame(0, (0.0, 0.0, 0.5))
    skin = SkinModel.fit([train.left], [train.labels_left])
    scene = ToyScene(ideal_rig, seed=4)
    pipe = VisionPipeline(ideal_rig, skin_model=skin, config=PipelineConfig(learn_frames=3))
    assert pipe.config.refine.method == "axis"
    err = []
    for i in range(30):
        p = np.array([-0.03 + 0.002 * i, 0.005, 0.5 + 0.001 * i])
        f = scene.frame(i / 30, p, hand=i >= 3)
        e = pipe.process(StereoFrame(i, i / 30, f.left, f.right))
        if i >= 6:
            assert e.found, e.reason
            err.append(np.linalg.norm(e.p_cam - f.tip_cam))
    failed, ok = pipe.refine_stats
    assert ok >= 0.8 * (ok + failed) and ok >= 20, pipe.refine_stats
    assert np.sqrt(np.mean(np.square(err))) < 0.003


def _edge_points(win):
    """Midpoints between horizontally/vertically adjacent pixels of different value (x, y)."""
    b = win > 0
    hy, hx = np.nonzero(b[:, 1:] != b[:, :-1])
    vy, vx = np.nonzero(b[1:, :] != b[:-1, :])
    return np.concatenate([np.column_stack([hx + 0.5, hy]), np.column_stack([vx, vy + 0.5])]).astype(np.float64)


def _reference_axis_line(rig, side, mask, tip, from_radii, to_radii, width_tol, max_residual_px, min_points, **_):
    """The side-edge axis written plainly (pixel-pair crossings of the whole crop, the crop's border
    dropped, rectified with the rig's own call, the two-line fit with 2×2 matrices): (centre, slope,
    points, rms, v_mean), or None where it refuses."""
    r, uv, d0 = tip.cap_radius_px, np.asarray(tip.uv, float), np.asarray(tip.direction, float)
    end = uv + (to_radii + 1.0) * r * d0
    m = r * (1.0 + width_tol) + 2.0
    x0, y0 = (max(int(v), 0) for v in np.minimum(uv, end) - m)
    x1, y1 = (min(int(v) + 2, s) for v, s in zip(np.maximum(uv, end) + m, mask.shape[::-1]))
    e = _edge_points(mask[y0:y1, x0:x1])
    e = e[(e[:, 0] > 0) & (e[:, 0] < x1 - x0 - 1) & (e[:, 1] > 0) & (e[:, 1] < y1 - y0 - 1)] + (x0, y0)
    rel = e - uv
    along, off = rel @ d0, np.abs(rel[:, 0] * d0[1] - rel[:, 1] * d0[0])
    e = e[(along >= -0.5 * r) & (along <= (to_radii + 0.5) * r) & (off >= 0.4 * r) & (off <= 1.6 * r)]
    c, a = rig.rectify_points(np.array([uv, uv + 2.0 * r * d0]), side)
    p = rig.rectify_points(e, side)
    d = (a - c) / np.linalg.norm(a - c)
    keep = np.ones(len(p), bool)
    for _ in range(2):
        rel = p - c
        along, off = rel @ d, rel[:, 0] * d[1] - rel[:, 1] * d[0]
        use = keep & (along >= from_radii * r) & (along <= to_radii * r) & (np.abs(np.abs(off) - r) <= width_tol * r)
        sides = [use & (off <= 0), use & (off > 0)]
        if min(s.sum() for s in sides) < min_points:
            return None
        means = [p[s].mean(axis=0) for s in sides]
        q = p - np.where((off > 0)[:, None], means[1], means[0])
        evals, evecs = np.linalg.eigh(q[use].T @ q[use])
        d = evecs[:, 1] * np.sign(evecs[:, 1] @ d)
        mid = 0.5 * (means[0] + means[1])
        c = mid - ((mid - c) @ d) * d
        res = q @ np.array([d[1], -d[0]])
        keep = np.abs(res) <= max_residual_px
    return c, d[0] / d[1], tuple(int(s.sum()) for s in sides), np.sqrt(np.mean(res[use] ** 2)), p[use, 1].mean()


@pytest.mark.parametrize("rig_name", ["ideal_rig", "distorted_rig"])
def test_axis_line_equals_the_plain_two_line_fit(rig_name, request, rng):
    """The axis line's arithmetic (complex points, crossings inside the crop only, one rectification
    call per view) gives the plain fit's numbers to rounding on toy fingers, with and without lens
    distortion."""
    rig = request.getfixturevalue(rig_name)
    for k in range(10):
        c = np.array([300.0, 220.0]) + rng.uniform(0, 1, 2)
        r = rng.uniform(6.0, 9.0)
        mask, _ = _finger_mask(c, rng.uniform(10, 45) * (1 if k % 2 else -1), r)
        tip = _tip(mask, r, c)
        line = axis_line(rig, "right" if k % 3 else "left", mask, (0, 0), tip, **KW)
        ref = _reference_axis_line(rig, "right" if k % 3 else "left", mask, tip, **KW)
        assert not isinstance(line, str) and ref is not None, line
        np.testing.assert_allclose(line.centre, ref[0], rtol=0, atol=1e-9)
        assert line.slope == pytest.approx(ref[1], abs=1e-9)
        assert line.points == ref[2]
        assert line.rms_px == pytest.approx(ref[3], abs=1e-9) and line.v_mean == pytest.approx(ref[4], abs=1e-9)
        np.testing.assert_allclose(line.cap, rig.rectify_points(tip.uv, "right" if k % 3 else "left")[0], atol=1e-9)


def test_unrectified_points_of_an_undistorted_view_are_cv2s(ideal_rig, distorted_rig, rng):
    """The rectified pixels taken back to raw pixels: cv2.projectPoints' floats for a view without
    distortion (computed without the call), and back onto the raw pixels they came from."""
    from vishap.vision.stereo import _unrectify_points

    raw = rng.uniform((0, 0), (640, 480), (200, 2))
    for rig in (ideal_rig, distorted_rig):
        for side, K, d, R, P in (("left", rig.K_left, rig.dist_left, rig.R1, rig.P1),
                                 ("right", rig.K_right, rig.dist_right, rig.R2, rig.P2)):
            rect = rig.rectify_points(raw, side)
            rays = np.column_stack([(rect[:, 0] - P[0, 2]) / P[0, 0], (rect[:, 1] - P[1, 2]) / P[1, 1],
                                    np.ones(len(rect))]) @ R
            ref = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, d)[0].reshape(-1, 2)
            got = _unrectify_points(rig, rect, side)
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
            np.testing.assert_allclose(got, raw, rtol=0, atol=1e-6)


@pytest.mark.parametrize("rig_name", ["ideal_rig", "distorted_rig"])
def test_both_views_fitted_at_once_give_each_view_alone(rig_name, request, rng):
    """axis_lines (the pipeline's call: both views' points through one set of array operations)
    gives each view's axis_line to rounding, and a view that cannot be measured refuses the pair
    with that view's reason."""
    from vishap.vision.axis_disparity import axis_lines

    rig = request.getfixturevalue(rig_name)
    for k in range(6):
        cl = np.array([330.0, 230.0]) + rng.uniform(0, 1, 2)
        ang, r = rng.uniform(15, 40) * (1 if k % 2 else -1), rng.uniform(6.5, 9.0)
        ml, _ = _finger_mask(cl, ang, r)
        mr, _ = _finger_mask(cl - (55.0 + rng.uniform(0, 1), 0.0), ang + rng.uniform(-3, 3), r * 0.97)
        views = [("left", ml, (0, 0), _tip(ml, r, cl)), ("right", mr, (0, 0), _tip(mr, 0.97 * r, cl - (55.0, 0.0)))]
        both = axis_lines(rig, views, **KW)
        for (side, m, org, tip), line in zip(views, both):
            alone = axis_line(rig, side, m, org, tip, **KW)
            assert not isinstance(line, str) and not isinstance(alone, str), (line, alone)
            np.testing.assert_allclose(line.centre, alone.centre, rtol=0, atol=1e-10)
            assert line.slope == pytest.approx(alone.slope, abs=1e-12) and line.points == alone.points
            assert line.rms_px == pytest.approx(alone.rms_px, abs=1e-10)
            assert line.v_mean == pytest.approx(alone.v_mean, abs=1e-10)
    flat, _ = _finger_mask((270.1, 230.2), 80.0, 8.0)  # the right view's finger along the rows
    views[1] = ("right", flat, (0, 0), _tip(flat, 8.0, (270.1, 230.2)))
    got = axis_lines(rig, views, **KW)
    assert got[0] == got[1] and "rows in the right view" in got[0]


def test_edge_crossings_of_any_crop_size_are_the_pixel_pairs_that_differ(rng):
    """The crossings come from grids cached by crop width (rows rounded up to a power of two): crops
    of one width and different heights, below and above each cached height, give the crossings of
    the plain per-pixel-pair rule, in its order."""
    from vishap.vision.axis_disparity import _inner_crossings

    def plain(crop):
        b = crop > 0
        hy, hx = np.nonzero(b[1:-1, 1:] != b[1:-1, :-1])
        vy, vx = np.nonzero(b[1:, 1:-1] != b[:-1, 1:-1])
        return np.concatenate([(hx + 0.5) + 1j * (hy + 1.0), (vx + 1.0) + 1j * (vy + 0.5)])

    for h in (3, 5, 31, 32, 33, 64, 65, 40, 7, 130):
        crop = ((rng.random((h, 37)) > 0.6) * 255).astype(np.uint8)
        got = _inner_crossings(crop)
        assert np.array_equal(got, plain(crop)), h
    assert len(_inner_crossings(np.zeros((20, 20), np.uint8))) == 0


def test_one_unrectified_point_in_plain_floats_is_the_array_form(ideal_rig, distorted_rig, rng):
    """The refined pair's two pixels go back to raw pixels one at a time in plain floats (a view
    without distortion) or through the array form (with distortion): the same pixels either way."""
    from vishap.vision.stereo import _unrectify_point, _unrectify_points

    for rig in (ideal_rig, distorted_rig):
        for side in ("left", "right"):
            for u, v in rng.uniform((0, 0), (640, 480), (20, 2)):
                np.testing.assert_allclose(_unrectify_point(rig, float(u), float(v), side),
                                           _unrectify_points(rig, (u, v), side)[0], rtol=0, atol=1e-9)


def test_the_axis_level_starts_from_its_prior_and_weighs_the_two_by_their_noise_once_known(rng):
    """Before any pair the level is the prior's (no offset, σ 0.15 px) and the blend about the plain
    mean of the axis and the cap fits; fed offsets ``axis − cap`` of a steady bias, the level
    converges on it and the axis's share on the inverse-variance weight σc² / (σc² + σa²); the blend
    then takes the bias off the axis."""
    from vishap.vision.axis_disparity import AxisLevel

    lv = AxisLevel(3.0, 0.16, 0.25, 0.15)
    w0 = 0.25 ** 2 / (0.25 ** 2 + 0.16 ** 2 + 0.15 ** 2)
    assert lv.level_px == 0.0 and lv.axis_weight() == pytest.approx(w0)
    assert lv.blend(10.4, 10.0) == pytest.approx(10.0 + 0.4 * w0)
    for k in range(600):  # 20 s at 30 Hz, the axis 0.12 px over the cap fits plus both fits' noise
        lv.add(k / 30, 0.12 + rng.normal(0.0, np.hypot(0.16, 0.25)))
    assert lv.level_px == pytest.approx(0.12, abs=0.05)
    w = 0.25 ** 2 / (0.25 ** 2 + 0.16 ** 2)
    assert lv.axis_weight() == pytest.approx(w, abs=0.01) and lv.axis_weight() < w
    assert lv.blend(10.12, 10.0) == pytest.approx(10.0 + lv.axis_weight() * (0.12 - lv.level_px), abs=1e-12)
    with pytest.raises(ValueError, match="tau_s"):
        AxisLevel(0.0, 0.16, 0.25, 0.15)


def test_the_axis_level_follows_a_change_over_its_time_constant():
    """The level is an exponentially weighted mean over ``tau_s``: a step of the offset from 0.1 to
    0.3 px is 63 % taken after one time constant, and all of it after many."""
    from vishap.vision.axis_disparity import AxisLevel

    lv = AxisLevel(2.0, 0.16, 0.25, 0.15)
    t = 0.0
    while t < 20.0:
        lv.add(t, 0.1)
        t += 0.01
    t0 = t
    while t < t0 + 2.0:
        lv.add(t, 0.3)
        t += 0.01
    assert lv.level_px == pytest.approx(0.1 + 0.2 * (1 - np.exp(-1.0)), abs=0.01)
    while t < t0 + 30.0:
        lv.add(t, 0.3)
        t += 0.01
    # 400 effective pairs against the prior: shrunk by 1 %
    assert lv.level_px == pytest.approx(0.3, abs=5e-3) and lv.level_px < 0.3


def test_the_refinement_takes_the_level_off_the_axis(ideal_rig, rng):
    """Given a level, the refined pair's disparity is the level's blend of the axis (less the level)
    and the cap fits, and the pair reports its own offset ``axis − cap`` for the level to follow."""
    from vishap.vision.axis_disparity import AxisLevel
    from vishap.vision.stereo import RefineConfig, refine_tip_pair

    cl = np.array([330.0, 230.0]) + rng.uniform(0, 1, 2)
    disp, ang, r = 60.3, 25.0, 8.0
    ml, _ = _finger_mask(cl, ang, r)
    mr, _ = _finger_mask(cl - (disp, 0.0), ang, r)
    tl, tr = _tip(ml, r, cl), _tip(mr, r, cl - (disp, 0.0))
    masks = {"left": (ml, (0, 0)), "right": (mr, (0, 0))}
    plain = refine_tip_pair(ideal_rig, None, None, tl, tr, RefineConfig(method="axis"), masks=masks)
    cap = tl.uv[0] - tr.uv[0]
    axis = 2.0 * (plain.uv_left[0] - plain.uv_right[0]) - cap  # the fixed mean's axis share is 0.5
    assert plain.axis_offset_px == pytest.approx(axis - cap, abs=1e-9)
    lv = AxisLevel(3.0, 0.16, 0.25, 0.15)
    for k in range(90):
        lv.add(k / 30, 0.4)
    ref = refine_tip_pair(ideal_rig, None, None, tl, tr, RefineConfig(method="axis"), masks=masks, level=lv)
    w = lv.axis_weight()
    assert 0.35 < lv.level_px < 0.4
    assert ref.ok and ref.uv_left[0] - ref.uv_right[0] == pytest.approx(w * (axis - lv.level_px) + (1 - w) * cap, abs=1e-6)
    assert ref.axis_offset_px == pytest.approx(axis - cap, abs=1e-9)


def test_the_pipeline_follows_the_axis_level_by_default_and_not_without_it(ideal_rig):
    """The default pipeline keeps one level and feeds it every refined pair (the level moves off the
    prior and its weight grows); ``axis_level_s=0`` keeps the fixed mean (no level), and a reset of
    the tracking forgets the level."""
    import dataclasses

    from vishap.vision.capture import StereoFrame
    from vishap.vision.pipeline import PipelineConfig, VisionPipeline
    from vishap.vision.skin_model import SkinModel
    from vishap.vision.toy import ToyScene

    train = ToyScene(ideal_rig, seed=11).frame(0, (0.0, 0.0, 0.5))
    skin = SkinModel.fit([train.left], [train.labels_left])
    scene = ToyScene(ideal_rig, seed=4)
    cfg = PipelineConfig(learn_frames=3)
    pipe = VisionPipeline(ideal_rig, skin_model=skin, config=cfg)
    off = VisionPipeline(ideal_rig, skin_model=skin,
                         config=dataclasses.replace(cfg, refine=dataclasses.replace(cfg.refine, axis_level_s=0.0)))
    assert off.axis_level is None and pipe.axis_level is not None
    for i in range(20):
        f = scene.frame(i / 30, np.array([-0.03 + 0.002 * i, 0.005, 0.5]), hand=i >= 3)
        pipe.process(StereoFrame(i, i / 30, f.left, f.right))
    w0 = pipe.axis_level.axis_weight()
    assert pipe.refine_stats[1] >= 10 and pipe.axis_level.level_px != 0.0
    pipe.reset_tracking()
    assert pipe.axis_level.level_px == 0.0 and pipe.axis_level.axis_weight() < w0


def test_the_levels_settings_are_checked_by_name():
    """A negative or infinite time constant, or a σ that is not positive, is refused with the field's
    name (a negative constant used to turn the level off without a word)."""
    from vishap import ConfigError
    from vishap.vision.stereo import RefineConfig

    assert RefineConfig(method="axis", axis_level_s=0.0).axis_level_s == 0.0  # 0: the fixed mean
    for kw, field in ((dict(axis_level_s=-1.0), "refine.axis_level_s"), (dict(axis_level_s=float("inf")), "refine.axis_level_s"),
                      (dict(axis_sigma_px=0.0), "refine.axis_sigma_px"), (dict(cap_sigma_px=-0.1), "refine.cap_sigma_px"),
                      (dict(axis_prior_px=float("nan")), "refine.axis_prior_px")):
        with pytest.raises(ConfigError) as e:
            RefineConfig(method="axis", **kw)
        assert e.value.field == field
