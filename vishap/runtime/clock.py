"""The simulated clock of batch runs, replay and benchmarks.

Algorithms never read the wall clock; loops ask a clock. ``SimClock`` advances only when told,
so a batch run is deterministic and as fast as the machine allows. Live runs take their time from
the servo process's timer (:meth:`vishap.runtime.live.LiveServo.now`).
"""
from __future__ import annotations

__all__ = ["SimClock"]


class SimClock:
    """Simulated time in seconds, advanced explicitly in integer ticks of ``dt``.

    Time is kept as an integer tick count so that 1000 steps of 1 ms give exactly 1.0 s.
    """

    def __init__(self, dt: float = 1e-3, t0: float = 0.0):
        if not dt > 0:
            raise ValueError(f"SimClock: dt must be > 0 s, got {dt!r}")
        self.dt = float(dt)
        self.t0 = float(t0)
        self.ticks = 0

    def now(self) -> float:
        return self.t0 + self.ticks * self.dt

    def advance(self, n: int = 1) -> float:
        if n < 0:
            raise ValueError(f"SimClock.advance: n must be >= 0, got {n}")
        self.ticks += int(n)
        return self.now()
