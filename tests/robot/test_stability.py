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
