"""Real-time periodic loops in Python on Linux: SCHED_FIFO, timer slack, sleep-then-spin.

A 1 kHz Python loop on a loaded 2-core machine misses deadlines by milliseconds under the
default scheduler. What works (measured on this project's machines):

- ``SCHED_FIFO`` (permitted as root or with CAP_SYS_NICE); :func:`enter_realtime` falls back
  gracefully and says why when it is not permitted;
- a small timer slack (``prctl(PR_SET_TIMERSLACK)``), so ``sleep`` wakes when asked;
- sleep until shortly before the deadline, then spin the last ~0.2 ms. Never a pure busy-wait
  under SCHED_FIFO: the kernel's RT throttling would stall the process 50 ms every second;
- when the host itself stalls for several ms (a virtual machine does), the loop does not try to
  run the missed periods at full speed: it reports how many periods were missed so that
  simulated time can catch up in one step.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["RealtimeStatus", "enter_realtime", "set_timer_slack", "PeriodicTimer", "Tick", "LatenessStats"]

_PR_SET_TIMERSLACK = 29


@dataclass(frozen=True)
class RealtimeStatus:
    """What :func:`enter_realtime` obtained."""

    sched_fifo: bool
    priority: int
    timer_slack_ns: int | None
    message: str


def set_timer_slack(ns: int) -> int | None:
    """Set this thread's timer slack in nanoseconds; returns it, or None where unsupported."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        if libc.prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(int(ns)), 0, 0, 0) != 0:
            return None
        return int(ns)
    except (OSError, AttributeError):
        return None


def enter_realtime(priority: int = 50, *, timer_slack_ns: int = 1000) -> RealtimeStatus:
    """Switch the calling process to SCHED_FIFO at ``priority`` where permitted.

    Never raises for lack of permission: the returned status says what was obtained and, if
    SCHED_FIFO was refused, what to do about it.
    """
    slack = set_timer_slack(timer_slack_ns)
    if not hasattr(os, "sched_setscheduler"):
        return RealtimeStatus(False, 0, slack, "SCHED_FIFO unavailable on this platform; running best-effort")
    try:
        lo, hi = os.sched_get_priority_min(os.SCHED_FIFO), os.sched_get_priority_max(os.SCHED_FIFO)
        prio = int(min(max(priority, lo), hi))
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
        return RealtimeStatus(True, prio, slack, f"SCHED_FIFO priority {prio}")
    except PermissionError:
        return RealtimeStatus(
            False, 0, slack,
            "SCHED_FIFO refused (needs root or CAP_SYS_NICE, e.g. `setcap cap_sys_nice+ep` on the "
            "interpreter, or an rtprio limit in /etc/security/limits.conf); running best-effort, "
            "expect millisecond lateness under load",
        )
    except OSError as exc:
        return RealtimeStatus(False, 0, slack, f"SCHED_FIFO failed ({exc}); running best-effort")


@dataclass(frozen=True)
class Tick:
    """One wake-up of a :class:`PeriodicTimer`."""

    index: int          # period index since start (counts missed periods too)
    deadline: float     # s, on the timer's clock
    lateness: float     # s, wake time minus deadline (>= 0 up to clock resolution)
    periods: int        # periods this tick stands for: 1 normally, >1 after missed periods


class PeriodicTimer:
    """Wake every ``period`` seconds: sleep until ``spin`` before the deadline, then spin.

    ``wait()`` returns a :class:`Tick`. When the loop falls more than ``max_lateness_periods``
    behind (a host stall), the missed deadlines are skipped and ``Tick.periods`` says how many
    periods elapsed, so simulated time catches up instead of the loop racing to replay them.
    """

    def __init__(self, period: float, *, spin: float = 2e-4, max_lateness_periods: int = 1, clock=time.perf_counter):
        if not period > 0:
            raise ValueError(f"PeriodicTimer: period must be > 0 s, got {period!r}")
        self.period = float(period)
        self.spin = float(min(max(spin, 0.0), period))
        self.max_late = int(max_lateness_periods)
        self._clock = clock
        self._start = None
        self._k = 0

    def start(self) -> None:
        self._start = self._clock()
        self._k = 0

    @property
    def started_at(self) -> float | None:
        """The clock reading at :meth:`start` (period k's deadline is ``started_at + k·period``)."""
        return self._start

    def wait(self) -> Tick:
        if self._start is None:
            self.start()
        clock = self._clock
        k_prev = self._k
        k = k_prev + 1
        deadline = self._start + k * self.period
        now = clock()
        remaining = deadline - now - self.spin
        if remaining > 0:
            time.sleep(remaining)
        while clock() < deadline:
            pass
        now = clock()
        lateness = now - deadline
        periods = 1
        behind = int(lateness // self.period)
        if behind > self.max_late:
            # host stall: skip to the current period; report how many periods passed
            k += behind
            periods += behind
            deadline = self._start + k * self.period
            lateness = now - deadline
        self._k = k
        return Tick(k, deadline, max(lateness, 0.0), periods)


class LatenessStats:
    """Collects per-tick lateness (seconds) and summarises it in microseconds."""

    def __init__(self, capacity: int = 1 << 20):
        self._buf = np.zeros(int(capacity))
        self._n = 0
        self.missed_periods = 0

    def add(self, tick: Tick) -> None:
        if self._n < self._buf.shape[0]:
            self._buf[self._n] = tick.lateness
            self._n += 1
        self.missed_periods += tick.periods - 1

    @property
    def values(self) -> np.ndarray:
        return self._buf[: self._n]

    def summary(self, late_threshold_s: float = 1e-3) -> dict:
        x = self.values
        if x.size == 0:
            return {"ticks": 0}
        us = x * 1e6
        return {
            "ticks": int(x.size),
            "lateness_us_median": float(np.median(us)),
            "lateness_us_p99": float(np.percentile(us, 99)),
            "lateness_us_p999": float(np.percentile(us, 99.9)),
            "lateness_us_max": float(us.max()),
            # a skipped (missed) period counts as a late tick
            "late_over_1ms_fraction": float(
                (np.count_nonzero(x > late_threshold_s) + self.missed_periods) / (x.size + self.missed_periods)
            ),
            "missed_periods": int(self.missed_periods),
        }
