"""Deterministic multi-rate scheduling on a simulated clock (batch runs, replay, tests).

The base rate is the servo's (1 kHz). Each task has its own rate (vision 30 Hz, scene 60 Hz,
tactile 1 kHz …) and runs at the first base tick at or after each of its due times, in the order
the tasks were added — so a vision result produced at tick k is seen by the servo at tick k.
Rates need not divide the base rate: a 30 Hz task runs at ticks 0, 34, 67, 100, …
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from vishap.runtime.clock import SimClock

__all__ = ["MultiRateScheduler"]


@dataclass
class _Task:
    name: str
    rate_hz: float
    fn: Callable[[float], object]
    count: int = 0          # runs so far
    next_tick: int = 0      # base tick of the next run
    start_tick: int = 0     # base tick of the first run


class MultiRateScheduler:
    """Runs named callbacks ``fn(t)`` at their own rates on a :class:`SimClock`."""

    def __init__(self, base_rate_hz: float = 1000.0):
        if not base_rate_hz > 0:
            raise ValueError(f"MultiRateScheduler: base_rate_hz must be > 0, got {base_rate_hz!r}")
        self.base_rate_hz = float(base_rate_hz)
        self.clock = SimClock(1.0 / self.base_rate_hz)
        self._tasks: list[_Task] = []

    def add(self, name: str, rate_hz: float, fn: Callable[[float], object]) -> None:
        if not 0 < rate_hz <= self.base_rate_hz:
            raise ValueError(f"task '{name}': rate_hz must be in (0, {self.base_rate_hz}], got {rate_hz!r}")
        if any(t.name == name for t in self._tasks):
            raise ValueError(f"task '{name}' added twice")
        self._tasks.append(_Task(name, float(rate_hz), fn, next_tick=self.clock.ticks, start_tick=self.clock.ticks))

    def counts(self) -> dict[str, int]:
        return {t.name: t.count for t in self._tasks}

    def step(self) -> float:
        """Run every task due at the current tick, then advance one base tick; returns that t."""
        tick = self.clock.ticks
        t = self.clock.now()
        for task in self._tasks:
            if tick >= task.next_tick:
                task.fn(t)
                task.count += 1
                # due time of the next run, in base ticks, rounded up (1e-9 guards float error)
                task.next_tick = task.start_tick + math.ceil(task.count * self.base_rate_hz / task.rate_hz - 1e-9)
        self.clock.advance()
        return t

    def run(self, duration_s: float) -> None:
        n = int(round(duration_s * self.base_rate_hz))
        for _ in range(n):
            self.step()
