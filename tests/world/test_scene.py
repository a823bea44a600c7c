import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.world.modes import default_modes, load_modes
from vishap.world.scene import available_scenes, load_scene

WALL = """name: w
passive_object: {shape: plate, size_m: [0.04, 0.04, 0.003], mass_kg: 0.012, mount_offset_m: [0.03, 0.0, 0.0]}
objects:
  - {name: wall, kind: wall, mode: hard_wall, normal: [0, 0, 1], offset_m: -0.15,
     centre: [0.2, 0, -0.15], extent_m: [0.1, 0.1]}
"""
BUTTON = """  - {name: key, kind: button, mode: key_click, position: [0.2, 0.05, -0.15], normal: [0, 0, 1],
     width_m: 0.018, height_m: 0.018, travel_m: 0.004, trigger_depth_m: 0.0018}
"""
FABRIC = """  - {name: cloth, kind: fabric, mode: fabric_stroke, normal: [0, 0, 1], offset_m: -0.15,
     centre: [0.2, 0, -0.15], extent_m: [0.1, 0.1],
     surface: {mu_static: 0.45, mu_kinetic: 0.35, texture_period_m: 0.001, roughness_rms_m: 0.00005}}
"""


def test_shipped_scenes_load():
    assert {"wall", "button", "fabric", "panel"} <= set(available_scenes())
    for name in available_scenes():
        s = load_scene(name)
        assert s.objects and s.file.endswith(f"{name}.yaml")
        for o in s.objects:
            assert np.allclose(o.R.T @ o.R, np.eye(3)) and np.isclose(np.linalg.det(o.R), 1.0)
            assert o.mode is default_modes().modes[o.mode_name]
    b = load_scene("button").object("key")
    assert b.spec.trigger_depth_m == 0.0018 and b.mode.law.kind == "button_click"
    f = load_scene("fabric").object("fabric")
    assert f.spec.surface.mu_static == 0.45 and f.spec.surface.texture == "woven"
    assert load_scene("panel").object("key_b").spec.stiffness.k_resist_n_m == 500.0


def test_normal_is_normalised_and_geometry(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(WALL.replace("normal: [0, 0, 1]", "normal: [0, 0, 3]"))
    o = load_scene(p).objects[0]
    assert np.allclose(o.normal, [0, 0, 1])
    assert o.signed_distance([0.2, 0.0, -0.14]) == pytest.approx(0.01)
    assert o.signed_distance([0.2, 0.0, -0.152]) == pytest.approx(-0.002)
    assert o.signed_distance([0.28, 0.0, -0.15]) == pytest.approx(0.03)  # 30 mm beyond the edge
    assert np.allclose(o.project([0.4, 0.01, -0.1]), [0.25, 0.01, -0.15])


@pytest.mark.parametrize(
    "text, field, words",
    [
        (WALL.replace("normal: [0, 0, 1]", "normal: [0, 0, 0]"), "objects.0.normal", "non-zero"),
        (WALL.replace("centre: [0.2, 0, -0.15]", "centre: [0.2, 0, -0.14]"), "objects.0", "off the plane"),
        (WALL.replace("mode: hard_wall", "mode: jelly"), "objects.0.mode", "unknown interaction mode"),
        (WALL.replace("mode: hard_wall", "mode: key_click"), "objects.0.mode", "not a 'wall'"),
        (WALL.replace("extent_m: [0.1, 0.1]", "extent_m: [0.1, -0.1]"), "objects.0.extent_m", "greater than 0"),
        (WALL.replace("kind: wall", "kind: door"), "objects.0", "kind"),
        (WALL.replace("mass_kg: 0.012", "mass_kg: 0"), "passive_object.mass_kg", "greater than 0"),
        (WALL + BUTTON.replace("trigger_depth_m: 0.0018", "trigger_depth_m: 0.005"), "objects.1", "travel_m"),
        (WALL + BUTTON.replace("name: key", "name: wall"), "objects.1.name", "duplicate"),
        (WALL + FABRIC.replace("mu_kinetic: 0.35", "mu_kinetic: 0.6"), "objects.1.surface", "mu_kinetic"),
        (WALL.replace("  - {name", "  - {colour: red, name"), "objects.0.colour", "Extra inputs"),
        (WALL.split("objects:")[0] + "objects: []\n", "objects", "at least 1"),
    ],
)
def test_bad_scene_files_name_file_and_field(tmp_path, text, field, words):
    p = tmp_path / "bad_scene.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_scene(p)
    msg = str(exc.value)
    assert "bad_scene.yaml" in msg and exc.value.field.startswith(field), msg
    assert words in msg


def test_unknown_scene_name():
    with pytest.raises(ConfigError, match="unknown scene 'nope'.*wall"):
        load_scene("nope")


def test_mode_database_fits_laws_to_kinds(tmp_path):
    db = default_modes()
    assert "click" in db.modes["key_click"].allows and db.modes["hard_wall"].allows == ["slide"]
    p = tmp_path / "modes.yaml"
    p.write_text("odd: {kinds: [button], allows: [press], target: centre,"
                 " law: {kind: wall_spring, stiffness_n_m: 100}}\n")
    with pytest.raises(ConfigError, match="odd.kinds"):
        load_modes(p)
    p.write_text("odd: {kinds: [wall], allows: [press], target: centre, law: {kind: wall_spring}}\n")
    with pytest.raises(ConfigError) as exc:
        load_modes(p)
    assert exc.value.field == "odd.law.stiffness_n_m"
