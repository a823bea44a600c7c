import numpy as np

from vishap.runtime.rt import LatenessStats, PeriodicTimer, RealtimeStatus, Tick, enter_realtime


class FakeClock:
    """A clock that advances only when read, by a scripted amount, so timing is exact."""

    def __init__(self, steps):
        self.t = 0.0
        self.steps = list(steps)

    def __call__(self):
        if self.steps:
            self.t += self.steps.pop(0)
        return self.t


def test_timer_ticks_at_the_period():
    import time

    timer = PeriodicTimer(0.002, spin=0.0005)
    t0 = time.perf_counter()  # before start: the deadlines count from start (a preemption in between is not the timer's)
    timer.start()
    ticks = [timer.wait() for _ in range(20)]
    elapsed = time.perf_counter() - t0
    # every period is accounted for, skipped ones included (a loaded host may stall the loop)
    assert sum(t.periods for t in ticks) == ticks[-1].index
    assert all(b.index - a.index == b.periods for a, b in zip(ticks, ticks[1:]))
    # the loop never runs ahead of its deadlines
    assert elapsed >= ticks[-1].index * 0.002 - 1e-4
    assert all(t.lateness >= 0 for t in ticks)


def test_host_stall_is_reported_as_missed_periods_not_replayed():
    # start at 0; the first wait finds the clock 10.5 ms late (a host stall)
    clock = FakeClock([0.0, 0.0105, 0.0, 0.0, 0.0])
    timer = PeriodicTimer(0.001, spin=0.0, clock=clock)
    timer.start()
    tick = timer.wait()
    assert tick.periods == 10  # nine missed periods + this one: simulated time catches up
    assert tick.index == 10
    assert tick.lateness < 0.001


def test_lateness_stats_count_missed_periods_as_late():
    s = LatenessStats()
    for lat in [1e-5] * 997 + [2e-3]:
        s.add(Tick(0, 0.0, lat, 1))
    s.add(Tick(0, 0.0, 1e-5, 3))  # two periods skipped
    summary = s.summary()
    assert summary["ticks"] == 999
    assert summary["missed_periods"] == 2
    assert summary["late_over_1ms_fraction"] == np.float64(3 / 1001)
    assert summary["lateness_us_max"] == 2000.0


def test_enter_realtime_always_reports_what_it_got():
    import os

    import multiprocessing as mp

    # run in a child so the test runner itself keeps its scheduler
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        status = pool.apply(enter_realtime, (10,))
    assert isinstance(status, RealtimeStatus)
    assert status.message
    if status.sched_fifo:
        assert status.priority >= 1
    else:
        assert "SCHED_FIFO" in status.message
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
