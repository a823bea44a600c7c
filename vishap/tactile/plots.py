"""Charts of drive signals: time series with the contact state, spectrogram of a stroke, channel emphasis."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_drive", "plot_spectrogram", "plot_emphasis", "sleeve_mix"]

STATE_COLOURS = {"none": "#ffffff", "concentrated": "#fde0c5", "distributed": "#c6e2f5", "slip": "#d9f0d3"}


def sleeve_mix(regions: np.ndarray, pins: np.ndarray) -> np.ndarray:
    """One listenable sleeve signal: the regional actuators plus the mean pin drive."""
    return regions.sum(axis=0) + pins.mean(axis=0)


def _shade_states(ax, tick_t, states):
    if len(tick_t) == 0:
        return
    start = 0
    for k in range(1, len(states) + 1):
        if k == len(states) or states[k] != states[start]:
            ax.axvspan(tick_t[start], tick_t[min(k, len(tick_t) - 1)], color=STATE_COLOURS.get(states[start], "#eee"),
                       lw=0, zorder=0)
            start = k


def plot_drive(path, fs, glove, regions, pins, tick_t, states, title="tactile drive signals") -> Path:
    from vishap._core.results import new_figure, save_figure

    t = np.arange(glove.shape[-1]) / fs + (tick_t[0] if len(tick_t) else 0.0)
    fig, axes = new_figure(4, 1, figsize=(9, 7), sharex=True)
    series = [("glove 0–20 Hz", glove[None]), ("regions R1–R3", regions), ("pins (24)", pins), ("sleeve mix", sleeve_mix(regions, pins)[None])]
    for ax, (name, y) in zip(axes, series):
        _shade_states(ax, tick_t, states)
        if name.startswith("pins"):
            ax.plot(t, y.T, lw=0.3, alpha=0.5)
        elif name.startswith("regions"):
            for i in range(y.shape[0]):
                ax.plot(t, y[i], lw=0.4, label=f"R{i + 1}")
            ax.legend(loc="upper right", fontsize=7)
        else:
            ax.plot(t, y[0], lw=0.5)
        ax.set_ylabel(name, fontsize=8)
    axes[-1].set_xlabel("time (s)   background: contact state (orange concentrated, blue distributed, green slip)")
    axes[0].set_title(title)
    return save_figure(fig, path)


def plot_spectrogram(path, fs, signal_1d, tick_t=None, speed=None, title="sleeve spectrogram") -> Path:
    from scipy import signal as sps

    from vishap._core.results import new_figure, save_figure

    nper = int(0.05 * fs)
    f, tt, S = sps.spectrogram(signal_1d, fs=fs, nperseg=nper, noverlap=nper * 3 // 4)
    keep = f <= 450
    fig, ax = new_figure(figsize=(9, 4))
    db = 10 * np.log10(S[keep] + 1e-12)
    mesh = ax.pcolormesh(tt, f[keep], db, shading="auto", cmap="magma", vmin=db.max() - 35, vmax=db.max())
    ax.figure.colorbar(mesh, ax=ax, pad=0.12, label="dB")
    for fb in (20, 200, 400):
        ax.axhline(fb, color="w", lw=0.6, ls="--")
    if speed is not None and tick_t is not None:
        ax2 = ax.twinx()
        ax2.plot(np.asarray(tick_t) - tick_t[0], speed, color="c", lw=1.0)
        ax2.set_ylabel("finger speed (m/s)", color="c")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("frequency (Hz); dashed: PHSM band edges")
    ax.set_title(title)
    return save_figure(fig, path)


def plot_emphasis(path, table: dict[str, dict[str, float]], title="channel emphasis per contact state") -> Path:
    """Grouped bars: RMS drive of each channel group for each state."""
    from vishap._core.results import new_figure, save_figure

    states = list(table)
    channels = list(next(iter(table.values())))
    fig, ax = new_figure(figsize=(8, 4))
    w = 0.8 / len(channels)
    for i, ch in enumerate(channels):
        ax.bar(np.arange(len(states)) + i * w, [table[s][ch] for s in states], w, label=ch)
    ax.set_xticks(np.arange(len(states)) + 0.4 - w / 2, states)
    ax.set_ylabel("RMS drive")
    ax.legend(fontsize=8)
    ax.set_title(title)
    return save_figure(fig, path)
