"""The servo in its own real-time process, fed through shared-memory mailboxes.

Live runs keep the 1 kHz servo away from vision: the servo process enters SCHED_FIFO (when
permitted), optionally pins itself to one CPU, and each period reads the newest target record
(non-blocking), steps the servo object and publishes the newest state record. Frames never
cross into it. A host stall of several ms is caught up by stepping the servo once per missed
period (simulated plants keep their own time consistent with the wall clock).

The servo object is built *inside* the child by ``make_servo()`` (a picklable callable, e.g. a
``functools.partial`` of a module-level function) and must offer
``step(t: float, target: ndarray | None) -> ndarray`` returning ``state_size`` floats, and may offer
``finish() -> object`` (called once after the loop; its result comes back in the report).
``target`` is None until the producer's first write (the mailbox's own sequence number says so),
so that a record that reads as zeros is never mistaken for "nothing yet": once anything was
written, every value the servo object gets is something a producer wrote, and judging it is the
servo object's task.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vishap.runtime.mailbox import Mailbox
from vishap.runtime.rt import LatenessStats, PeriodicTimer, enter_realtime

__all__ = ["LiveServo", "LiveServoReport"]


@dataclass
class LiveServoReport:
    """What the servo process measured about itself."""

    realtime: str                 # what enter_realtime obtained
    sched_fifo: bool
    lateness: dict                # LatenessStats.summary()
    step_us_median: float         # cost of one servo step inside the process
    steps: int
    error: str | None = None
    lateness_s: np.ndarray | None = None   # every tick's lateness, for charts
    result: object = None                  # what the servo object's ``finish()`` returned (if it has one)


def _servo_main(make_servo, period, priority, cpu, target_name, target_size, state_name, state_size,
                stop, conn, realtime) -> None:
    report = None
    try:
        if cpu is not None and hasattr(os, "sched_setaffinity"):
            os.sched_setaffinity(0, {cpu})
        status = enter_realtime(priority) if realtime else None
        servo = make_servo()
        targets = Mailbox.attach(target_name, target_size)
        states = Mailbox.attach(state_name, state_size)
        timer = PeriodicTimer(period)
        stats = LatenessStats()
        costs = np.zeros(1 << 20)
        n = 0
        timer.start()
        conn.send(("ready", timer.started_at))
        t_sim = 0.0
        clock = time.perf_counter
        while not stop.is_set():
            tick = timer.wait()
            target, written = targets.read()
            if not written:
                target = None
            c0 = clock()
            for _ in range(tick.periods):  # catch up after a host stall
                t_sim += period
                state = servo.step(t_sim, target)
            if n < costs.shape[0]:
                costs[n] = clock() - c0
            n += 1
            states.write(state)
            stats.add(tick)
        report = LiveServoReport(
            realtime=status.message if status else "best-effort (real-time not requested)",
            sched_fifo=bool(status and status.sched_fifo),
            lateness=stats.summary(),
            step_us_median=float(np.median(costs[: min(n, costs.shape[0])]) * 1e6) if n else float("nan"),
            steps=n,
            lateness_s=stats.values.copy(),
            result=servo.finish() if hasattr(servo, "finish") else None,
        )
        targets.close(unlink=False)
        states.close(unlink=False)
    except Exception as exc:  # reported to the parent, which raises it
        report = LiveServoReport("", False, {}, float("nan"), 0, error=f"{type(exc).__name__}: {exc}")
    conn.send(report)
    conn.close()


class LiveServo:
    """Start/stop a real-time servo process; hand it targets, read its state."""

    def __init__(self, make_servo: Callable[[], object], *, target_size: int, state_size: int,
                 period: float = 1e-3, priority: int = 80, cpu: int | None = None, realtime: bool = True):
        self._make = make_servo
        self.period = float(period)
        self.priority = int(priority)
        self.cpu = cpu
        self.realtime = bool(realtime)
        self.targets = Mailbox(target_size)
        self.states = Mailbox(state_size)
        self._ctx = mp.get_context("spawn")
        self._stop = self._ctx.Event()
        self._proc = None
        self._conn = None
        self._started_at = None

    def start(self, timeout: float = 60.0) -> None:
        parent, child = self._ctx.Pipe(duplex=False)
        self._conn = parent
        self._proc = self._ctx.Process(
            target=_servo_main,
            args=(self._make, self.period, self.priority, self.cpu, self.targets.name, self.targets.size,
                  self.states.name, self.states.size, self._stop, child, self.realtime),
            daemon=True,
        )
        self._proc.start()
        child.close()
        if not parent.poll(timeout):
            self.stop()
            raise RuntimeError("servo process did not start")
        first = parent.recv()
        if isinstance(first, LiveServoReport):  # failed before the loop
            self._proc.join(5)
            self.close()
            raise RuntimeError(f"servo process failed: {first.error}")
        self._started_at = float(first[1])

    def now(self) -> float:
        """The servo's time now (s), read in this process: its timer counts periods from its start on the
        host's monotonic clock (``time.perf_counter``, shared by all processes) and skips missed ones,
        so the servo's simulated time is the time since that start, also while the servo is starved."""
        if self._started_at is None:
            raise RuntimeError("LiveServo.now: the servo process is not started")
        return time.perf_counter() - self._started_at

    def write_target(self, values) -> None:
        self.targets.write(values)

    def read_state(self) -> tuple[np.ndarray, int]:
        return self.states.read()

    def stop(self, timeout: float = 10.0) -> LiveServoReport:
        self._stop.set()
        report = None
        if self._conn is not None and self._conn.poll(timeout):
            report = self._conn.recv()
        if self._proc is not None:
            self._proc.join(timeout)
            if self._proc.is_alive():
                self._proc.kill()
        self.close()
        if report is None:
            raise RuntimeError("servo process ended without a report")
        if report.error:
            raise RuntimeError(f"servo process failed: {report.error}")
        return report

    def close(self) -> None:
        for box in (self.targets, self.states):
            try:
                box.close()
            except (AttributeError, FileNotFoundError):
                pass

    def __enter__(self) -> "LiveServo":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        if self._proc is not None and self._proc.is_alive():
            self.stop()
