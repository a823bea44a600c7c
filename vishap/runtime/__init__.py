"""The multi-rate runtime: clocks, latest-value hand-over, real-time periodic loops, safety.

VisHap runs vision at camera rate (20–60 Hz), the haptic servo at 1 kHz and the scene at 60 Hz.
These modules keep those loops apart so that vision never stalls the servo:

- :mod:`~vishap.runtime.clock`      simulated time for batch runs
- :mod:`~vishap.runtime.core`       the core cycle written once: scene step, target record, servo step
- :mod:`~vishap.runtime.assembly`   the device (``open_device``) and the guarded servo step around it
- :mod:`~vishap.runtime.mailbox`    latest-value hand-over in shared memory (seqlock; never blocks)
- :mod:`~vishap.runtime.rt`         SCHED_FIFO, timer slack, sleep-then-spin periodic timer, lateness
- :mod:`~vishap.runtime.multirate`  deterministic multi-rate scheduling on a simulated clock
- :mod:`~vishap.runtime.safety`     the target guard: hold or retreat on stale, lost or bad input
- :mod:`~vishap.runtime.live`       the servo in its own real-time process, fed through mailboxes
"""
from vishap.runtime.clock import SimClock
from vishap.runtime.mailbox import Mailbox
from vishap.runtime.multirate import MultiRateScheduler
from vishap.runtime.rt import LatenessStats, PeriodicTimer, RealtimeStatus, enter_realtime
from vishap.runtime.safety import Fault, GuardDecision, TargetGuard

__all__ = [
    "SimClock",
    "Mailbox",
    "MultiRateScheduler",
    "LatenessStats",
    "PeriodicTimer",
    "RealtimeStatus",
    "enter_realtime",
    "Fault",
    "GuardDecision",
    "TargetGuard",
]
