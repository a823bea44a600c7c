"""Showing the augmented view live: an OpenCV window where a display exists, else a matplotlib
figure, else a clear statement that there is none (the loop then goes on without a window).

The live loop calls :func:`open_live_view` once and :meth:`LiveView.show` per composed frame; ``show``
returns False once the user closed the window (or pressed ``q`` / Esc), so the loop can stop.
"""
from __future__ import annotations

import os
import sys

import numpy as np

__all__ = ["LiveView", "open_live_view", "display_reason"]


def display_reason(env=None) -> str | None:
    """None when a graphical display can be reached, else why not."""
    env = os.environ if env is None else env
    if sys.platform.startswith("linux") and not (env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")):
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    return None


def _opencv_has_gui() -> bool:
    import cv2

    info = cv2.getBuildInformation()
    gui = info.split("GUI:", 1)[1].splitlines()[0].strip() if "GUI:" in info else "NONE"
    return gui.upper() != "NONE"


class LiveView:
    """A window titled ``title``; ``backend`` is ``opencv``, ``matplotlib`` or None (no window, see ``reason``)."""

    def __init__(self, title: str = "vishap AR", *, env=None):
        self.title = title
        self.backend: str | None = None
        self.reason = display_reason(env)
        self._fig = self._im = None
        if self.reason is not None:
            return
        if _opencv_has_gui():
            self.backend = "opencv"
            return
        try:
            import matplotlib

            if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
                matplotlib.use("TkAgg")
            import matplotlib.pyplot as plt

            plt.ion()
            self._plt = plt
            self.backend = "matplotlib"
        except Exception as exc:  # noqa: BLE001 — any GUI toolkit failure means: no window
            self.reason = f"no window toolkit (OpenCV is built without GUI; matplotlib: {exc})"

    @property
    def available(self) -> bool:
        return self.backend is not None

    def show(self, image_bgr: np.ndarray) -> bool:
        """Show one frame; False when there is no window or the user closed it."""
        if self.backend == "opencv":
            import cv2

            cv2.imshow(self.title, image_bgr)
            key = cv2.waitKey(1) & 0xFF
            if key in (ord("q"), 27) or cv2.getWindowProperty(self.title, cv2.WND_PROP_VISIBLE) < 1:
                self.close()
                return False
            return True
        if self.backend == "matplotlib":
            rgb = np.ascontiguousarray(image_bgr[:, :, ::-1])
            if self._fig is None:
                self._fig, ax = self._plt.subplots(num=self.title)
                ax.set_axis_off()
                self._im = ax.imshow(rgb)
            elif not self._plt.fignum_exists(self._fig.number):
                self.close()
                return False
            else:
                self._im.set_data(rgb)
            self._plt.pause(0.001)
            return True
        return False

    def close(self) -> None:
        if self.backend == "opencv":
            import cv2

            cv2.destroyWindow(self.title)
        elif self.backend == "matplotlib" and self._fig is not None:
            self._plt.close(self._fig)
        self.backend = None


def open_live_view(title: str = "vishap AR", *, env=None, stream=None) -> LiveView:
    """A :class:`LiveView`; when no window can be opened, says so once on ``stream`` (stderr)."""
    view = LiveView(title, env=env)
    if not view.available:
        print(f"vishap: the AR view is not shown live: {view.reason}", file=stream or sys.stderr)
    return view
