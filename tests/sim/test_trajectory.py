"""Scripted finger motion and the device path: contact on the surface, reachability, determinism (no rendering)."""
from __future__ import annotations

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.robot.kinematics import fk, ik, link_points
from vishap.sim.device import REACHABLE_BOX
from vishap.sim.sequence import SequenceSpec, frame_state, prepare
from vishap.sim.state import TIP_RADIUS_M
from vishap.sim.trajectory import HIDDEN_PHASES, PHASES, Trajectory, load_trajectory

SURFACE_Z = -0.150


@pytest.mark.parametrize("scene", ["wall", "button", "fabric"])
@pytest.mark.parametrize("seed", [0, 3])
def test_finger_touches_the_passive_object_on_the_surface(scene, seed):
    p = prepare(SequenceSpec(scene=scene, frames=345, seed=seed))
    assert p.scene_spec.surface_z_m == SURFACE_Z
    n_contact, n_rest = 0, 0
    for t in p.times:
        st, geo = frame_state(p, float(t))
        ee = st.ee_robot
        assert np.all(ee >= REACHABLE_BOX[0] - 1e-12) and np.all(ee <= REACHABLE_BOX[1] + 1e-12)
        np.testing.assert_allclose(fk(ik(ee)), ee, atol=1e-9)
        np.testing.assert_allclose(st.device_points_robot[1:], link_points(ik(ee)), atol=1e-12)
        np.testing.assert_allclose(st.device_points_robot[-1], ee, atol=1e-9)
        if not geo["in_contact"]:
            continue
        n_contact += 1
        bottom = st.tip_robot - np.array([0.0, 0.0, TIP_RADIUS_M])
        top = st.passive_object.top_centre_robot(ee)
        # the cap's lowest point lies on the passive object's top face, inside it
        assert bottom[2] == pytest.approx(top[2], abs=1e-9)
        half = np.array(st.passive_object.size_m[:2]) / 2.0
        assert np.all(np.abs(bottom[:2] - top[:2]) <= half - 0.003)
        assert bottom[2] == pytest.approx(SURFACE_Z - geo["press_depth"], abs=1e-9)
        if geo["press_depth"] == 0.0:
            n_rest += 1
            assert bottom[2] == pytest.approx(SURFACE_Z, abs=1e-9)
    assert n_contact > 40
    if scene != "button":  # the key is pressed in right after it is touched
        assert n_rest > 0


def test_hand_free_frames_timestamps_and_phases():
    p = prepare(SequenceSpec(scene="wall", frames=400, seed=1))
    np.testing.assert_allclose(p.times, np.arange(400) / 30.0)
    phases = [PHASES[frame_state(p, float(t))[1]["phase"]] for t in p.times]
    hidden = [not frame_state(p, float(t))[0].hand_visible for t in p.times[:10]]
    assert phases[:10] == ["hand_free"] * 10 and all(hidden)
    assert phases[10] != "hand_free"
    for name in ("approach", "press", "slide", "lift", "fast_sweep", "pause", "occlusion", "leave", "away"):
        assert name in phases, name
    assert set(HIDDEN_PHASES) < set(PHASES)


def test_same_seed_same_motion_other_seed_differs():
    def tips(seed):
        p = prepare(SequenceSpec(scene="fabric", frames=120, seed=seed))
        return np.array([frame_state(p, float(t))[0].tip_robot for t in p.times])

    a, b, c = tips(5), tips(5), tips(6)
    np.testing.assert_array_equal(a, b)
    assert np.max(np.abs(a - c)) > 1e-3


def test_velocity_is_the_derivative_of_the_tip_path():
    spec, path = load_trajectory("wall")
    tr = Trajectory(spec, surface_z_m=SURFACE_Z, touch_region=[[0.15, -0.07], [0.25, 0.07]], seed=2, file=path)
    for t in np.linspace(0.5, 9.0, 40):
        h = 1e-5
        fd = (tr.sample(t + h).tip_robot - tr.sample(t - h).tip_robot) / (2 * h)
        np.testing.assert_allclose(tr.velocity(t), fd, atol=2e-4)
    speeds = [np.linalg.norm(tr.velocity(t)) for t in np.arange(0.4, 11.0, 1 / 30)]
    assert max(speeds) > 0.3  # the fast sweep


def test_fps_option_changes_frame_times():
    p = prepare(SequenceSpec(scene="button", frames=5, fps=60.0, hand_free_frames=2))
    np.testing.assert_allclose(p.times, np.arange(5) / 60.0)
    assert [frame_state(p, float(t))[0].hand_visible for t in p.times[:2]] == [False, False]


def test_contact_outside_touch_region_is_an_error(tmp_path):
    spec, _ = load_trajectory("button")
    bad = tmp_path / "bad.yaml"
    import yaml

    data = spec.model_dump()
    data["segments"][1]["contact"] = [0.25, 0.0]
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="segments.1.contact"):
        prepare(SequenceSpec(scene="button", frames=3, trajectory=str(bad)))


@pytest.mark.parametrize("field,value,match", [("segments", [{"phase": "jump", "duration_s": 1}], "segments.0.phase"),
                                                ("fps", -3, "fps"), ("segments", [], "segments")])
def test_bad_trajectory_file_names_the_field(tmp_path, field, value, match):
    import yaml

    spec, _ = load_trajectory("wall")
    data = spec.model_dump()
    data[field] = value
    bad = tmp_path / "t.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=match):
        load_trajectory(bad)


def test_unknown_names_and_values():
    with pytest.raises(ConfigError, match="unknown scene"):
        prepare(SequenceSpec(scene="moon", frames=3))
    with pytest.raises(ConfigError, match="unknown trajectory"):
        prepare(SequenceSpec(scene="wall", frames=3, trajectory="nope"))
    with pytest.raises(ConfigError, match="frames"):
        prepare(SequenceSpec(scene="wall", frames=-1))
    with pytest.raises(ConfigError, match="written for scenes"):
        prepare(SequenceSpec(scene="button", frames=3, trajectory="wall"))
    with pytest.raises(ConfigError, match="lighting"):
        prepare(SequenceSpec(scene="wall", frames=3, lighting="disco"))
