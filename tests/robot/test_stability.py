"""Stability runs and their classification; the stability bench's record (a coarse smoke run)."""
import argparse
import math

import pytest

from vishap.robot.stability import RunSpec, classify, passivity_margin, run_free_space, run_wall, tip_damping


def test_default_gains_are_stable_in_free_space_and_on_a_moderate_wall():
    assert run_free_space(RunSpec())["outcome"] == "stable"
    assert run_wall(RunSpec(wall_k=2000.0, wall_b=5.0))["outcome"] == "stable"


def test_no_damping_diverges_and_long_delay_fails():
    assert run_free_space(RunSpec(kv=0.0))["outcome"] == "diverged"
    assert run_free_space(RunSpec(delay_ticks=20))["outcome"] in ("oscillating", "diverged")


def test_one_substep_hides_a_stiff_wall_instability():
    stiff = dict(wall_k=32000.0, wall_b=0.0, duration_s=0.9)
    assert run_wall(RunSpec(substeps=10, **stiff))["outcome"] != "stable"
    assert run_wall(RunSpec(substeps=1, **stiff))["outcome"] == "stable"


def test_classify_rules():
    base = dict(status="ok", ptp_settled_mm=0.0, faults=0, max_error_mm=1.0, ripple_last_half_mm=0.01)
    assert classify(base) == "stable"
    assert classify({**base, "ripple_last_half_mm": 0.5}) == "oscillating"
    assert classify({**base, "max_error_mm": 100.0}) == "diverged"
    assert classify({**base, "ptp_settled_mm": math.inf}) == "diverged"


def test_colgate_bound():
    b = tip_damping()
    assert 0.0 < b < 0.1
    T = 1e-3
    assert passivity_margin(2 * b / T * 0.99, 0.0, b, T) > 0
    assert passivity_margin(2 * b / T * 1.01, 0.0, b, T) < 0
    assert passivity_margin(0.0, 2 * b, b, T) < 0


@pytest.mark.slow
def test_bench_stability_quick(tmp_path):
    from vishap.bench import stability

    rec = stability.run(argparse.Namespace(out=str(tmp_path), substeps=10, quick=True))
    assert (tmp_path / "stability.png").stat().st_size > 1000
    assert rec["runs"] == len(rec["records"]) >= 10
    for r in rec["records"]:
        assert r["outcome"] in ("stable", "oscillating", "diverged")
        assert {"kp", "kv", "a", "rate_hz", "delay_ticks", "wall_k", "wall_b", "substeps", "sweep"} <= set(r)


def test_each_mode_in_its_own_contact_set_up():
    # the wall's own set-up (Λ_z = 0: only the law holds the finger) with the measured jitter: its
    # 800 N/m spring is stable with its 2 N·s/m and not without damping
    from vishap.robot.stability import contact_law

    own = RunSpec(mode="hard_wall", wall_k=800.0, wall_b=2.0, sensor="encoder", jitter=True)
    r = run_wall(own)
    assert r["outcome"] == "stable" and r["lambda_state"] == 2  # the core's object gain engaged: Λ = the mode's
    assert run_wall(RunSpec(**{**own.as_dict(), "wall_b": 0.0}))["outcome"] != "stable"
    key = contact_law("key_click", 2500.0, 2.0)
    assert key.lambda_contact == (1.0, 1.0, 0.0) and key.k3 == 2500.0


def test_renderable_stiffness_takes_every_mode_and_the_data_sheet():
    from vishap.bench.stability import renderable_stiffness

    def rec(mode, K, B, ok):
        return {"sweep": "contact", "mode": mode, "wall_k": K, "wall_b": B, "outcome": "stable" if ok else "oscillating",
                "colgate_passive": False}

    recs = [rec(m, K, B, K <= lim) for m, lim in (("hard_wall", 2500), ("key_click", 1600))
            for K in (800, 1600, 2500, 5000) for B in (1, 2)]
    recs += [rec(m, K, 4, True) for m in ("hard_wall", "key_click") for K in (800, 1600, 2500, 5000)]
    r = renderable_stiffness(recs)
    assert r["max_stiffness_n_m"] == [1600.0, 1600.0, 3500.0]  # the weakest mode; capped at 3.5 N/mm
    assert r["per_mode"]["hard_wall"]["max_stiffness_n_m"] == 2500.0
    assert r["passive_but_unstable"] == 0 and r["stable_but_not_passive"] == sum(x["outcome"] == "stable" for x in recs)


def test_a_light_touch_does_not_engage_a_stiff_wall_and_a_firm_press_shows_it_rings():
    # why the sweep presses twice: 1 N on 3.5 kN/m stays within the engage depth (the object gain stays at
    # the surface, laterally held) and settles; 3 N engages the wall's own Λ and rings
    light = RunSpec(mode="hard_wall", wall_k=3500.0, wall_b=2.0, sensor="encoder", jitter=True, push_n=1.0)
    r = run_wall(light)
    assert r["outcome"] == "stable" and r["lambda_state"] == 1
    assert run_wall(RunSpec(**{**light.as_dict(), "push_n": 3.0}))["outcome"] != "stable"
