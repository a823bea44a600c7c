"""Charts a demo writes: force against depth (VisHap Fig. 6), a timeline of the run, and for
fabric the tactile spectrogram and contact-state timeline (HAPTEX §II-C, PHSM §2.4)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vishap.apps.metrics import linear_fit
from vishap._core.results import new_figure, save_figure

__all__ = ["plot_force_depth", "plot_timeline", "plot_spectrogram", "plot_contact_states"]


def plot_force_depth(path, depth_m, force_n, *, title: str, fit: bool = True) -> Path:
    """Normal force against the fingertip's distance to the surface (negative = under it), mm/N."""
    fig, ax = new_figure(figsize=(5.2, 3.8))
    d = np.asarray(depth_m, float)
    f = np.asarray(force_n, float)
    ax.plot(-1e3 * d, f, ".", ms=2, alpha=0.5, label="servo samples (1 kHz)")
    if fit:
        sel = d >= 1e-4
        a, b, r2 = linear_fit(d[sel], f[sel])
        if np.isfinite(a):
            xs = np.linspace(0.0, d[sel].max(), 20)
            ax.plot(-1e3 * xs, a * xs + b, "r-", lw=1.5, label=f"fit {a:.0f} N/m, R²={r2:.4f}")
    ax.axvline(0.0, color="k", lw=0.6)
    ax.set_xlabel("fingertip distance to surface (mm, negative = under it)")
    ax.set_ylabel("force along the normal (N)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    return save_figure(fig, path)


def plot_timeline(path, servo: dict, vision: dict, *, title: str, normal=(0.0, 0.0, 1.0)) -> Path:
    """Heights along the normal (finger, device, vision estimate, target) and forces over time."""
    n = np.asarray(normal, float)
    fig, (a1, a2) = new_figure(2, 1, figsize=(7.5, 5.0), sharex=True)
    t = servo["t"]
    a1.plot(t, 1e3 * servo["finger_point"] @ n, "k-", lw=1, label="finger pad (truth)")
    a1.plot(t, 1e3 * servo["device_point"] @ n, "b-", lw=1, label="device contact point")
    a1.plot(t, 1e3 * servo["X_d"] @ n, "g--", lw=0.8, label="target X_d")
    if len(vision.get("t", [])):
        ok = vision["found"].astype(bool)
        a1.plot(vision["t"][ok], 1e3 * vision["finger_robot"][ok] @ n, "r.", ms=3, label="vision (finger pad)")
    a1.set_ylabel("height along normal (mm)")
    a1.legend(fontsize=7, ncol=2)
    a1.grid(alpha=0.3)
    a1.set_title(title)
    a2.plot(t, servo["F_contact"] @ n, "m-", lw=1, label="contact force on finger (N)")
    a2.plot(t, np.linalg.norm(servo["F_cmd"], axis=1), "c-", lw=0.8, label="|device command| (N)")
    guard = servo.get("guard")
    if guard is not None and np.any((guard == 1) | (guard == 2)):
        top = float(np.max(np.abs(servo["F_cmd"]))) + 0.1
        a2.fill_between(t, 0, top, where=guard == 1, color="orange", alpha=0.25, label="hold")
        a2.fill_between(t, 0, top, where=guard == 2, color="red", alpha=0.2, label="retreat")
    a2.set_xlabel("time (s)")
    a2.set_ylabel("N")
    a2.legend(fontsize=7)
    a2.grid(alpha=0.3)
    return save_figure(fig, path)


def plot_spectrogram(path, t: np.ndarray, signal: np.ndarray, fs_hz: float, *, title: str) -> Path:
    """Spectrogram of a tactile drive signal (0–400 Hz shown: the PHSM bands)."""
    from scipy.signal import spectrogram

    fig, ax = new_figure(figsize=(7.0, 3.6))
    x = np.asarray(signal, float)
    nper = int(min(256, max(16, len(x) // 8)))
    f, tt, S = spectrogram(x, fs=fs_hz, nperseg=nper, noverlap=nper * 3 // 4)
    t0 = float(t[0]) if len(t) else 0.0
    S_db = 10 * np.log10(S + 1e-12)
    m = ax.pcolormesh(tt + t0, f, S_db, shading="auto", vmin=S_db.max() - 60, vmax=S_db.max())
    for fb in (20.0, 200.0):
        ax.axhline(fb, color="w", lw=0.6, ls="--")
    ax.set_ylim(0, min(400.0, fs_hz / 2))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title(title)
    fig.colorbar(m, ax=ax, label="dB")
    return save_figure(fig, path)


def plot_contact_states(path, t: np.ndarray, state_codes: np.ndarray, labels: list[str],
                        force_n: np.ndarray, *, title: str) -> Path:
    """Contact state (one row per state) over time above the normal force."""
    fig, (a1, a2) = new_figure(2, 1, figsize=(7.0, 3.8), sharex=True, gridspec_kw={"height_ratios": [1, 1]})
    codes = np.asarray(state_codes, int)
    for k, name in enumerate(labels):
        on = codes == k
        a1.fill_between(t, k - 0.4, k + 0.4, where=on, step="mid", alpha=0.8)
    a1.set_yticks(range(len(labels)))
    a1.set_yticklabels(labels, fontsize=8)
    a1.set_title(title)
    a2.plot(t, force_n, "k-", lw=0.8)
    a2.set_ylabel("normal force (N)")
    a2.set_xlabel("time (s)")
    a2.grid(alpha=0.3)
    return save_figure(fig, path)
