import numpy as np
import pytest

from vishap.world.force_laws import ButtonClick, FabricFriction, WallSpring, make_law, saturate
from vishap.world.scene import load_scene, surface_frame

N = np.array([0.0, 0.0, 1.0])


def test_wall_is_a_linear_spring_in_depth_and_allows_sliding():
    law = WallSpring(N, -0.15, stiffness_n_m=800.0, damping_n_s_m=0.0)
    depths = np.linspace(-0.005, 0.008, 27)
    f = np.array([law.force_robot([0.2, 0.0, -0.15 - d], np.zeros(3))[2] for d in depths])
    assert np.all(f[depths <= 0] == 0.0)
    inside = depths > 0
    assert np.allclose(f[inside], 800.0 * depths[inside])
    # sliding along the surface: no tangential force, the same normal force
    F = law.force_robot([0.25, 0.03, -0.153], [0.3, -0.2, 0.0])
    assert F[0] == 0.0 and F[1] == 0.0 and F[2] == pytest.approx(2.4)
    # damping resists pressing in, never pulls the finger into the wall
    assert law.force_robot([0.2, 0, -0.151], [0, 0, -0.1])[2] == pytest.approx(0.8)
    assert WallSpring(N, -0.15, stiffness_n_m=800.0, damping_n_s_m=100.0).force_robot([0.2, 0, -0.151], [0, 0, 0.5])[2] == 0.0


def test_forces_saturate_at_the_device_limit():
    law = WallSpring(N, -0.15, stiffness_n_m=800.0, max_force_n=3.0)
    assert law.force_robot([0.2, 0.0, -0.17], np.zeros(3))[2] == pytest.approx(3.0)
    F = saturate(np.array([3.0, 4.0, 0.0]), 2.5)
    assert np.linalg.norm(F) == pytest.approx(2.5) and F[1] / F[0] == pytest.approx(4 / 3)
    assert np.all(saturate(np.array([np.nan, 1.0, 0.0]), 2.5) == 0.0)


def test_button_curve_two_slopes_click_and_hard_bottom():
    law = ButtonClick(N, -0.15, trigger_depth_m=0.0018, travel_m=0.004, k_resist_n_m=350.0,
                      k_click_n_m=60.0, k_bottom_n_m=2500.0, transition_m=0.0002)
    d = np.linspace(0.0, 0.005, 501)
    f = law.normal_force_curve(d)
    before = (d > 0) & (d < 0.0018)
    after = (d > 0.0021) & (d < 0.004)
    bottom = d > 0.0041
    assert np.polyfit(d[before], f[before], 1)[0] == pytest.approx(350.0, rel=1e-6)
    assert np.polyfit(d[after], f[after], 1)[0] == pytest.approx(60.0, rel=1e-6)
    assert np.polyfit(d[bottom], f[bottom], 1)[0] == pytest.approx(2500.0, rel=1e-6)
    # the click: force falls while the key goes deeper, gradually (over the transition only)
    drop = np.diff(f) < 0
    assert drop.any() and np.all((d[1:][drop] > 0.0018) & (d[1:][drop] <= 0.0020 + 1e-12))
    assert f.max() < 8.5
    # the force law (not the curve helper) gives the same numbers
    assert law.force_robot([0.2, 0, -0.151], np.zeros(3))[2] == pytest.approx(0.35)


def test_fabric_sticks_then_slides_with_kinetic_friction():
    R = surface_frame(N)
    law = FabricFriction(R, [0.2, 0.0, -0.15], mu_static=0.5, mu_kinetic=0.3, k_penalty_n_m=500.0,
                         k_tangential_n_m=600.0)
    assert np.all(law.force_robot([0.2, 0, -0.14], np.zeros(3)) == 0.0) and law.anchor is None
    z = -0.152  # 2 mm in: f_n = 1 N
    ft, sliding = [], []
    for i in range(200):  # stroke along +x at 50 mm/s for 5 mm, 1 kHz
        x = 0.2 + 0.05 * i * 1e-3
        F = law.force_robot([x, 0.0, z], [0.05, 0.0, 0.0])
        assert F[2] == pytest.approx(1.0)
        ft.append(F[0])
        sliding.append(law.sliding)
    ft = np.array(ft)
    assert ft[1] < 0 and not sliding[1]  # static friction opposes the motion
    peak = -ft.min()
    assert peak <= 0.5 + 0.6 * 0.05e-3 and peak > 0.45  # up to μ_s·f_n (one tick of overshoot)
    assert sliding[-1] and ft[-1] == pytest.approx(-0.3)  # kinetic friction μ_k·f_n
    # stopping re-sticks; lifting off clears the contact state
    law.force_robot([x, 0.0, z], np.zeros(3))
    assert not law.sliding
    law.force_robot([x, 0.0, -0.149], np.zeros(3))
    assert law.anchor is None


def test_make_law_builds_only_what_the_object_needs():
    assert type(make_law(load_scene("wall").objects[0])) is WallSpring
    key_b = make_law(load_scene("panel").object("key_b"))
    assert type(key_b) is ButtonClick and key_b.k1 == 500.0 and key_b.k2 == 60.0
    fab = make_law(load_scene("fabric").objects[0])
    assert type(fab) is FabricFriction and fab.mu_s == 0.45 and fab.mu_k == 0.35


def test_a_law_stiffer_than_the_device_renders_is_refused_naming_the_field(tmp_path):
    from vishap._core.errors import ConfigError
    from vishap.robot.gains import max_renderable_stiffness
    from vishap.robot.params import DEFAULT
    from vishap.world.modes import default_modes, load_modes

    # the shipped modes all pass, and nothing is allowed above the data sheet's 3.5 N/mm
    default_modes()
    assert max_renderable_stiffness(100.0) <= DEFAULT.datasheet_stiffness_n_m
    k = max_renderable_stiffness(2.0)
    p = tmp_path / "modes.yaml"
    p.write_text("key: {kinds: [button], allows: [press], target: centre, law: {kind: button_click, k_resist_n_m: 300,"
                 f" k_click_n_m: 60, k_bottom_n_m: {k * 1.5}, damping_n_s_m: 2.0}}}}\n")
    with pytest.raises(ConfigError) as exc:
        load_modes(p)
    assert exc.value.field == "key.law.k_bottom_n_m" and str(p) in str(exc.value)
    # less damping renders less: a wall at the 2 N·s/m limit is refused without damping
    p.write_text(f"w: {{kinds: [wall], allows: [slide], target: follow, law: {{kind: wall_spring, stiffness_n_m: {k}}}}}\n")
    if max_renderable_stiffness(0.0) < k:
        with pytest.raises(ConfigError, match="w.law.stiffness_n_m"):
            load_modes(p)


def test_a_scene_key_stiffer_than_renderable_is_refused_when_its_law_is_built():
    from dataclasses import replace

    from vishap._core.errors import ConfigError

    key = load_scene("button").object("key")
    make_law(key)  # the shipped key renders
    stiff = key.spec.stiffness.model_copy(update={"k_bottom_n_m": 1e5})
    obj = replace(key, spec=key.spec.model_copy(update={"stiffness": stiff}))
    with pytest.raises(ConfigError) as exc:
        make_law(obj)
    assert exc.value.field == "objects.key.k_bottom_n_m"
