"""``vishap bench tracking``: step/ramp responses with the default gains, and the X_d gap policies.

1. Step (2 cm along x, y, z; and z without gravity compensation) and ramp (5 cm/s along x)
   responses of the tip with the shipped default gains: settling time (2 % band), overshoot,
   steady-state error, ramp following error — ``tracking_steps.png``.
2. A smooth finger path (peak ≈ 0.15 m/s) sampled at 20 / 30 / 60 Hz with 30 ms vision latency,
   with and without 0.5 mm of measurement noise, bridged to 1 kHz by ``hold``, ``interpolate`` and
   ``extrapolate``: RMS / p95 error to the true path and the RMS force change per tick (how rough
   the motion is) — ``tracking_policies.png``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "step/ramp responses with the default gains and which X_d gap policy tracks a moving finger best"

POLICIES = ("hold", "interpolate", "extrapolate")


def add_arguments(parser) -> None:
    parser.add_argument("--gains", default=None, help="gains YAML (default: the shipped vishap/robot/gains.yaml)")
    parser.add_argument("--latency-ms", type=float, default=30.0, help="vision latency in the policy runs (default 30)")
    parser.add_argument("--duration", type=float, default=3.0, help="seconds per policy run (default 3)")
    parser.add_argument("--quick", action="store_true", help="one rate, short runs (for smoke tests)")


def _steps(gains) -> tuple[dict, list]:
    from vishap.robot.tracking import ramp_response, step_response

    runs = []
    for name, d, kw in [
        ("step_x", [1, 0, 0], {}),
        ("step_y", [0, 1, 0], {}),
        ("step_z", [0, 0, 1], {}),
        ("step_z_no_gravity_comp", [0, 0, 1], {"gravity_comp": False}),
    ]:
        r = step_response(gains, d, 0.02, **kw)
        runs.append((name, r))
    ramp = ramp_response(gains, [1, 0, 0], 0.05)
    runs.append(("ramp_x", ramp))
    summary = {}
    for name, r in runs:
        summary[name] = {k: v for k, v in r.items() if k not in ("t", "y", "ref")}
    return summary, runs


def _chart_steps(runs, out: Path, gains) -> Path:
    fig, axes = new_figure(1, 2, figsize=(12, 4.2))
    for name, r in runs:
        if name.startswith("step"):
            axes[0].plot(r["t"] * 1e3, r["y"] * 1e3, label=f"{name}: {r['overshoot_pct']:.1f} % os, ts {r['settling_time_s'] * 1e3:.0f} ms")
    axes[0].axhline(20.0, color="k", lw=0.6, ls=":")
    axes[0].set_xlabel("t (ms)")
    axes[0].set_ylabel("tip displacement along the step (mm)")
    axes[0].set_title(f"2 cm steps, Kp {gains.kp:g} N/m, Kv {gains.kv:g} N·s/m, a {gains.a:g} rad/s", fontsize=9)
    axes[0].legend(fontsize=7)
    name, r = runs[-1]
    axes[1].plot(r["t"] * 1e3, r["ref"] * 1e3, "k--", lw=0.8, label="target")
    axes[1].plot(r["t"] * 1e3, r["y"] * 1e3, label=f"tip (lag {r['following_error_m'] * 1e3:.2f} mm while moving)")
    axes[1].set_xlabel("t (ms)")
    axes[1].set_ylabel("mm")
    axes[1].set_title("5 cm/s ramp along x", fontsize=9)
    axes[1].legend(fontsize=8)
    return save_figure(fig, out / "tracking_steps.png")


def _policies(gains, rates, noises, latency_s, duration_s, quiet: bool = False) -> tuple[list, dict]:
    import itertools

    from vishap._core.results import progress
    from vishap.robot.tracking import moving_target

    recs, traces = [], {}
    cases = list(itertools.product(noises, rates, POLICIES))
    for noise, rate, pol in progress(cases, desc="bench tracking: policies", unit="run", quiet=quiet):
        r = moving_target(gains, pol, rate, noise_m=noise, latency_s=latency_s, duration_s=duration_s, seed=7)
        if noise == 0 and rate == rates[0]:
            traces[pol] = r
        recs.append({k: v for k, v in r.items() if k not in ("t", "p", "truth")})
    return recs, traces


def _chart_policies(recs, traces, out: Path, rates, noises) -> Path:
    fig, axes = new_figure(1, 3, figsize=(16, 4.4))
    w = 0.8 / len(POLICIES)
    x = np.arange(len(rates))
    for ax, metric, label in [(axes[0], "rms_error_m", "RMS error to the true finger path (mm)"), (axes[1], "force_roughness_n", "RMS force change per tick (N)")]:
        for i, pol in enumerate(POLICIES):
            for noise, hatch in zip(noises, ["", "//"]):
                vals = [next(r[metric] for r in recs if r["policy"] == pol and r["rate_hz"] == rate and r["noise_m"] == noise) for rate in rates]
                scale = 1e3 if metric.endswith("_m") else 1.0
                off = (i - 1) * w + (0.0 if noise == noises[0] else w / 2.2)
                ax.bar(x + off, np.array(vals) * scale, w / 2.2, color=f"C{i}", hatch=hatch,
                       label=f"{pol}{' + %.1f mm noise' % (noise * 1e3) if noise else ''}")
        ax.set_xticks(x, [f"{r:g} Hz" for r in rates])
        ax.set_ylabel(label)
        ax.set_title(label.split(" (")[0] + " vs X_d rate", fontsize=9)
    axes[0].legend(fontsize=7)
    ax = axes[2]
    any_tr = next(iter(traces.values()))
    t = any_tr["t"]
    k = (t >= t[-1] / 3) & (t <= 2 * t[-1] / 3)  # the middle third: past the start, whatever the run's length
    ax.plot(t[k], any_tr["truth"][k, 0] * 1e3, "k--", lw=1.0, label="finger (truth)")
    for i, pol in enumerate(POLICIES):
        ax.plot(t[k], traces[pol]["p"][k, 0] * 1e3, color=f"C{i}", lw=1.0, label=pol)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("x (mm)")
    ax.set_title(f"tip x at {rates[0]:g} Hz X_d", fontsize=9)
    ax.legend(fontsize=7)
    return save_figure(fig, out / "tracking_policies.png")


def run(args) -> dict:
    from vishap.robot.gains import load_gains

    gains, _ = load_gains(args.gains)
    out = Path(args.out)
    step_summary, runs = _steps(gains)
    png1 = _chart_steps(runs, out, gains)
    rates = [30.0] if args.quick else [20.0, 30.0, 60.0]
    noises = [0.0] if args.quick else [0.0, 0.0005]
    dur = 1.0 if args.quick else float(args.duration)
    recs, traces = _policies(gains, rates, noises, args.latency_ms / 1e3, dur, quiet=getattr(args, "quiet", False))
    png2 = _chart_policies(recs, traces, out, rates, noises)
    best = {}
    for noise in noises:
        for rate in rates:
            rs = [r for r in recs if r["rate_hz"] == rate and r["noise_m"] == noise]
            best[f"{rate:g}Hz_noise{noise * 1e3:g}mm"] = min(rs, key=lambda r: r["rms_error_m"])["policy"]
    return {
        "bench": "tracking",
        "gains": {"kp": gains.kp, "kv": gains.kv, "a": gains.a},
        "responses": step_summary,
        "policies": recs,
        "best_policy_by_rms_error": best,
        "latency_s": args.latency_ms / 1e3,
        "charts": [str(png1), str(png2)],
        "machine": machine_info(),
    }
