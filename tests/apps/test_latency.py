import numpy as np
import pytest

from vishap.bench.latency import _next_tick, budget
from vishap.runtime import MultiRateScheduler


@pytest.mark.parametrize("rate", [30.0, 60.0, 250.0, 1000.0])
def test_next_tick_follows_the_scheduler(rate):
    sched = MultiRateScheduler(1000.0)
    runs = []
    sched.add("x", rate, runs.append)
    sched.run(0.5)
    runs = np.array(runs)
    t = np.linspace(0.0, runs[-1] - 1e-4, 997)
    expect = runs[np.searchsorted(runs, t - 1e-12)]
    assert np.allclose(_next_tick(t, rate), expect)


def test_budget_adds_measured_costs_and_waits():
    vis = {"t": np.array([0.0, 1 / 30, 2 / 30]), "found": np.array([True, True, False]),
           "vision_ms": np.array([5.0, 5.0, 5.0]), "segment_ms": np.array([2.0, 2.0, 2.0]),
           "detect_ms": np.array([2.5, 2.5, 2.5]), "stereo_ms": np.array([0.5, 0.5, 0.5])}
    b = budget(vis, {"world_ms": np.array([0.2])}, {"tick_us": np.array([40.0, 60.0])}, scene_hz=60.0)
    assert b["frames"] == 2
    # frame 0: ready at 5 ms, scene tick at 17 ms (12 ms wait), target at 17.2 ms, servo at 18 ms
    assert b["parts"]["wait for scene tick"][0] == pytest.approx(12.0)
    assert b["parts"]["wait for servo tick"][0] == pytest.approx(0.8)
    assert b["total"][0] == pytest.approx(5.0 + 12.0 + 0.2 + 0.8 + 0.05)
