"""The live window says when there is no display, and showing a frame then does nothing."""
from __future__ import annotations

import io

import numpy as np

from vishap.ar.live_view import display_reason, open_live_view


def test_without_a_display_the_view_says_so_and_shows_nothing(monkeypatch):
    monkeypatch.setattr("sys.platform", "linux")
    env = {"PATH": "/usr/bin"}
    assert "no display" in display_reason(env)
    out = io.StringIO()
    view = open_live_view(env=env, stream=out)
    assert not view.available and "no display" in out.getvalue()
    assert view.show(np.zeros((4, 4, 3), np.uint8)) is False


def test_a_display_variable_counts_as_a_display(monkeypatch):
    monkeypatch.setattr("sys.platform", "linux")
    assert display_reason({"DISPLAY": ":0"}) is None
    assert display_reason({"WAYLAND_DISPLAY": "wayland-0"}) is None
