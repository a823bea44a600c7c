import pytest

from vishap.runtime.clock import SimClock
from vishap.runtime.multirate import MultiRateScheduler


def test_rates_over_one_second():
    s = MultiRateScheduler(1000.0)
    log = {"vision": [], "scene": [], "servo": []}
    s.add("vision", 30.0, log["vision"].append)
    s.add("scene", 60.0, log["scene"].append)
    s.add("servo", 1000.0, log["servo"].append)
    s.run(1.0)
    assert s.counts() == {"vision": 30, "scene": 60, "servo": 1000}
    # each run happens at the first tick at or after its due time
    assert log["vision"][:4] == pytest.approx([0.0, 0.034, 0.067, 0.1])
    assert log["servo"][-1] == pytest.approx(0.999)


def test_tasks_run_in_added_order_within_a_tick():
    s = MultiRateScheduler(100.0)
    order = []
    s.add("producer", 10.0, lambda t: order.append(("p", round(t, 6))))
    s.add("consumer", 100.0, lambda t: order.append(("c", round(t, 6))))
    s.step()
    assert order == [("p", 0.0), ("c", 0.0)]


def test_bad_rates_are_refused():
    s = MultiRateScheduler(1000.0)
    with pytest.raises(ValueError, match="rate_hz"):
        s.add("x", 2000.0, print)
    s.add("x", 10.0, print)
    with pytest.raises(ValueError, match="twice"):
        s.add("x", 10.0, print)


def test_sim_clock_is_exact_over_many_ticks():
    c = SimClock(1e-3)
    c.advance(1000)
    assert c.now() == 1.0
    with pytest.raises(ValueError):
        SimClock(0.0)
