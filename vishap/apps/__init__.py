"""The demo apps: the whole system assembled into one closed loop (issue 9).

``run_demo(DemoConfig(scene="wall"), "out/wall")`` renders a scripted finger with pyrender, runs
the frames through the vision pipeline, registration, world model, MuJoCo device and tactile layer
on a simulated clock, and writes the video, plots, ``log.npz`` and ``summary.json``.
``vishap.apps.replay.replay(log)`` re-runs vision/world/tactile from such a log.
"""
from vishap.apps.config import FAULT_KINDS, SCENES, DemoConfig, FaultSpec

__all__ = ["DemoConfig", "FaultSpec", "SCENES", "FAULT_KINDS", "run_demo"]


def run_demo(cfg: DemoConfig, out, *, progress: bool = False) -> dict:
    """Run one batch demo into ``out`` and return its summary (also written as ``summary.json``)."""
    from vishap.apps.loop import run_demo as _run

    return _run(cfg, out, progress=progress)
