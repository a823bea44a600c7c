"""``vishap bench stability``: where the servo loop fails, and the Colgate passivity bound beside it.

Sweeps (each run: :mod:`vishap.robot.stability`, MuJoCo with ``--substeps`` physics steps per 1 ms):

* ``kp_kv`` — Kp × Kv grid, free-space move, for the ideal sensor and the encoder model;
* ``filter`` — Eq. 5 filter constant ``a`` × Kp (Kv scaled to keep the damping ratio);
* ``rate`` — X_d update rate 20 Hz → 1 kHz × gap policy (hold / interpolate / extrapolate);
* ``delay`` — added transport delay (servo periods) × Kp;
* ``wall`` — virtual-wall stiffness K × damping B, with 1 and ``--substeps`` physics steps per
  period and both sensors: one physics step per period can hide the instability;
* ``contact`` — every interaction mode in its own contact set-up (its law with the stiffest part at
  K and damping B, its contact gain Λ, the encoder, ``--substeps``, the demos' measured servo jitter
  and the plant's Coulomb friction; the system's own servo step, a finger resting on the face and
  pushing with each of :data:`CONTACT_PUSH_N`), each point beside Colgate's bound ``b > K·T/2 + |B|``. From it:
  the largest stiffness renderable at each damping (every mode stable at every K up to it), never
  above the data sheet's 3.5 N/mm — the table ``gains.yaml`` holds and the force laws are checked
  against.

The chart draws the Colgate–Schenkel passivity bound ``b > K·T/2 + |B|`` for the arm's own tip
damping ``b`` and, dashed, for larger ``b`` a real device might have. Returns (and the command
saves as ``DIR/stability.json``) one record per run with its parameters and ``outcome``, a summary,
and the measured stable region that ``vishap/robot/gains.yaml`` is checked against.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure

HELP = "stability map of the servo loop (gains, filter, X_d rate, delay, wall stiffness) with the passivity bound"

KP = [25, 50, 100, 200, 400, 800, 1600, 3200, 6400, 12800, 25600]
KV = [0, 1, 2, 4, 8, 16, 32, 64, 128, 256]
A = [5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000]
RATES = [20, 30, 60, 125, 250, 500, 1000]
DELAYS = [0, 1, 2, 3, 5, 8, 12, 20]
WALL_K = [250, 500, 1000, 2000, 4000, 8000, 16000, 32000, 64000]
WALL_B = [0, 2, 5, 10, 20, 40]
CONTACT_K = [250, 500, 800, 1600, 2500, 3500, 5000]
CONTACT_B = [0, 1, 2, 4]
#: the finger's push in the contact sweep (N): a light touch and a firm press (the wall demo presses its
#: 800 N/m wall 3–5 mm, 2.4–4 N); 1 N alone stays within the object gain's engage depth on walls
#: stiffer than 3.3 kN/m, where the mode's own contact gain never takes over
CONTACT_PUSH_N = [1.0, 3.0]
SWEEP_KP = [200, 800, 3200]  # Kp of the filter and delay sweeps (Kv ∝ √Kp)
COLORS = {"stable": "tab:green", "oscillating": "tab:orange", "diverged": "tab:red"}


def add_arguments(parser) -> None:
    parser.add_argument("--substeps", type=int, default=10, help="physics steps per 1 ms servo period (default 10)")
    parser.add_argument("--quick", action="store_true", help="a coarse subset of every sweep (for smoke tests)")
    from vishap.scale.cli import add_engine_options

    add_engine_options(parser, sweep=True)


def _grids(quick: bool) -> dict:
    if not quick:
        from vishap.world.modes import default_modes

        return dict(kp=KP, kv=KV, a=A, rates=RATES, delays=DELAYS, wall_k=WALL_K, wall_b=WALL_B, sensors=["exact", "encoder"],
                    contact_k=CONTACT_K, contact_b=CONTACT_B, contact_push=CONTACT_PUSH_N, modes=sorted(default_modes().modes))
    return dict(
        kp=[800, 6400], kv=[0, 32], a=[500], rates=[20], delays=[12],
        wall_k=[32000], wall_b=[0], sensors=["exact"],
        contact_k=[800, 5000], contact_b=[2], contact_push=[1.0], modes=["hard_wall"],
    )


def _kv_for(kp: float) -> float:
    """Kv that keeps the damping ratio of the default gains (critically damped on every axis)."""
    from vishap.robot.controller import Gains

    g = Gains()
    return g.kv * math.sqrt(kp / g.kp)


def _tip_b_T() -> tuple[float, float]:
    from vishap.robot.params import DEFAULT
    from vishap.robot.stability import tip_damping

    return tip_damping(), DEFAULT.dt


def renderable_stiffness(recs: list[dict]) -> dict:
    """From the ``contact`` sweep: per damping B, the largest K at which every mode was stable at every
    swept K up to it, capped at the data sheet's stiffness; and per mode at its own damping."""
    from vishap.robot.params import DEFAULT
    from vishap.world.modes import default_modes

    cap = DEFAULT.datasheet_stiffness_n_m
    con = [r for r in recs if r["sweep"] == "contact"]
    ks = sorted({r["wall_k"] for r in con})
    bs = sorted({r["wall_b"] for r in con})

    def largest(rows) -> float:
        best = 0.0
        for K in ks:
            at = [r for r in rows if r["wall_k"] == K]
            if not at or any(r["outcome"] != "stable" for r in at):
                break
            best = float(K)
        return min(best, cap)

    table = [largest([r for r in con if r["wall_b"] == B]) for B in bs]
    db = default_modes()
    per_mode = {}
    for name in sorted({r["mode"] for r in con}):
        law = db.modes[name].law
        own_b = max([B for B in bs if B <= law.damping_n_s_m] or [bs[0]])
        per_mode[name] = {"damping_n_s_m": law.damping_n_s_m, "table_b": own_b,
                          "max_stiffness_n_m": largest([r for r in con if r["mode"] == name and r["wall_b"] == own_b])}
    agree = sum(1 for r in con if (r["outcome"] == "stable") == r["colgate_passive"])
    return {"damping_n_s_m": bs, "max_stiffness_n_m": table, "datasheet_stiffness_n_m": cap, "per_mode": per_mode,
            "colgate_agrees": agree, "colgate_points": len(con),
            "stable_but_not_passive": sum(1 for r in con if r["outcome"] == "stable" and not r["colgate_passive"]),
            "passive_but_unstable": sum(1 for r in con if r["outcome"] != "stable" and r["colgate_passive"])}


def _run_case(case: tuple) -> dict:
    """One run of a sweep (a Ray task under ``--workers``): a pure function of its case."""
    from vishap.robot.stability import RunSpec, run_free_space, run_wall

    sweep, kind, kw = case
    r = (run_wall if kind == "wall" else run_free_space)(RunSpec(**kw))
    r["sweep"] = sweep
    return r


def run_sweeps(substeps: int, quick: bool = False, *, workers: int = 1, address: str | None = None,
               progress: bool = False) -> list[dict]:
    """Every sweep's runs, listed first and then run as one set of cases (Ray tasks with ``workers``
    or ``address``); ``progress``: one bar over them, on stderr, on a terminal."""
    g = _grids(quick)
    cases: list[tuple] = []

    def add(sweep, kind, **kw):
        cases.append((sweep, kind, {"substeps": substeps, **kw}))

    for sensor in g["sensors"]:
        for kp in g["kp"]:
            for kv in g["kv"]:
                add("kp_kv", "free", kp=kp, kv=kv, sensor=sensor)
    for kp in ([800] if quick else SWEEP_KP):
        for a in g["a"]:
            add("filter", "free", kp=kp, kv=_kv_for(kp), a=a)
    for policy in ("hold", "extrapolate") if quick else ("hold", "interpolate", "extrapolate"):
        for rate in g["rates"]:
            add("rate", "free", rate_hz=rate, policy=policy)
    for kp in ([800] if quick else SWEEP_KP):
        for d in g["delays"]:
            add("delay", "free", kp=kp, kv=_kv_for(kp), delay_ticks=d)
    for mode in g["modes"]:
        for K in g["contact_k"]:
            for B in g["contact_b"]:
                for push in g["contact_push"]:
                    add("contact", "wall", sensor="encoder", wall_k=K, wall_b=B, mode=mode, jitter=True, push_n=push)
    for sub in sorted({1, substeps}):
        for sensor in g["sensors"]:
            for K in g["wall_k"]:
                for B in g["wall_b"]:
                    cases.append(("wall", "wall", {"substeps": sub, "sensor": sensor, "wall_k": K, "wall_b": B}))
    from vishap.robot.stability import passivity_margin
    from vishap.scale import map_cases

    recs = map_cases(_run_case, cases, workers=workers, address=address, progress=progress, desc="bench stability")
    b_tip, T = _tip_b_T()
    for r in recs:
        if r["sweep"] == "contact":
            r["colgate_passive"] = passivity_margin(r["wall_k"], r["wall_b"], b_tip, T) > 0
    return recs


def stable_region(recs: list[dict], substeps: int) -> dict:
    """The measured stable region: gains for which every sensor's run was stable."""
    kpkv = [r for r in recs if r["sweep"] == "kp_kv"]
    kps = sorted({r["kp"] for r in kpkv})
    kvs = sorted({r["kv"] for r in kpkv})
    ok = np.ones((len(kps), len(kvs)), dtype=bool)
    for r in kpkv:
        if r["outcome"] != "stable":
            ok[kps.index(r["kp"]), kvs.index(r["kv"])] = False
    filt = [r for r in recs if r["sweep"] == "filter"]
    a_vals = sorted({r["a"] for r in filt})
    a_ok = [a for a in a_vals if all(x["outcome"] == "stable" for x in filt if x["a"] == a)]
    # smallest a from which every larger swept a was stable at every swept Kp
    a_min = None
    for a in reversed(a_vals):
        if a not in a_ok:
            break
        a_min = a
    walls = [r for r in recs if r["sweep"] == "wall" and r["substeps"] == substeps]
    k_ok = [K for K in sorted({r["wall_k"] for r in walls}) if all(r["outcome"] == "stable" for r in walls if r["wall_k"] <= K and r["wall_b"] > 0)]
    delays = [r for r in recs if r["sweep"] == "delay" and r["kp"] == 800]
    d_ok = [r["delay_ticks"] for r in delays if r["outcome"] == "stable"]
    return {
        "kp_kv_grid": {"kp": kps, "kv": kvs, "stable": ok.astype(int).tolist()},
        "a_stable": a_ok,
        "a_min": a_min,
        "a_min_by_kp": {kp: _a_min([r for r in filt if r["kp"] == kp]) for kp in sorted({r["kp"] for r in filt})},
        "a_max": max(a_vals) if a_vals else None,
        "max_wall_stiffness_n_m": max(k_ok) if k_ok else None,
        "stable_delays_ticks_at_kp800": d_ok,
    }


def _a_min(runs: list[dict]):
    """The smallest swept a from which every larger swept a was stable (None if the largest fails)."""
    a_min = None
    for r in sorted(runs, key=lambda r: -r["a"]):
        if r["outcome"] != "stable":
            break
        a_min = r["a"]
    return a_min


def _colgate(ax, b: float, T: float, K_range) -> None:
    K = np.geomspace(K_range[0], K_range[1], 200)
    for bb, style in [(b, "-"), (1.0, "--"), (5.0, "--"), (20.0, "--")]:
        B = bb - K * T / 2
        m = B > 0
        if m.any():
            ax.plot(K[m], B[m], "k" + style, lw=1.2 if style == "-" else 0.8, alpha=0.8)
            ax.annotate(f"b={bb:.3g}", (K[m][0], B[m][0]), fontsize=7, xytext=(2, 2), textcoords="offset points")


def _scatter(ax, recs, x, y, title, xlog=True, ylog=False):
    for r in recs:
        ax.scatter(r[x] if r[x] > 0 or not xlog else 1e-1, r[y], c=COLORS[r["outcome"]], s=28, marker="s", edgecolors="none")
    if xlog:
        ax.set_xscale("log")
    if ylog:
        ax.set_yscale("symlog", linthresh=1.0)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(x)
    ax.set_ylabel(y)


def _worst_per_point(rows: list[dict]) -> list[dict]:
    """One row per (K, B): the one with the worst outcome over the finger's pushes."""
    rank = {"stable": 0, "oscillating": 1, "diverged": 2}
    worst: dict = {}
    for r in rows:
        k = (r["wall_k"], r["wall_b"])
        if k not in worst or rank[r["outcome"]] > rank[worst[k]["outcome"]]:
            worst[k] = r
    return list(worst.values())


def chart(recs: list[dict], out: Path, substeps: int, b_tip: float, T: float) -> Path:
    fig, axes = new_figure(3, 4, figsize=(18, 12.5))
    axes = axes.ravel()
    sensors = sorted({r["sensor"] for r in recs if r["sweep"] == "kp_kv"})
    for i, sensor in enumerate(sensors[:2]):
        sub = [r for r in recs if r["sweep"] == "kp_kv" and r["sensor"] == sensor]
        _scatter(axes[i], sub, "kp", "kv", f"free space, Kp × Kv ({sensor} sensor, {substeps} substeps)", ylog=True)
        _colgate(axes[i], b_tip, T, (min(KP), max(KP)))
    for j, (sub_n, sensor) in enumerate([(substeps, "exact"), (1, "exact"), (substeps, "encoder")]):
        ax = axes[2 + j]
        sub = [r for r in recs if r["sweep"] == "wall" and r["substeps"] == sub_n and r["sensor"] == sensor]
        if not sub:
            ax.set_visible(False)
            continue
        _scatter(ax, sub, "wall_k", "wall_b", f"virtual wall K × B ({sensor}, {sub_n} substep{'s' if sub_n > 1 else ''})", ylog=True)
        _colgate(ax, b_tip, T, (min(WALL_K), max(WALL_K)))
        ax.set_xlabel("wall stiffness K (N/m)")
        ax.set_ylabel("wall damping B (N·s/m)")
    f = [r for r in recs if r["sweep"] == "filter"]
    _scatter(axes[5], f, "a", "kp", "Eq. 5 filter constant a × Kp (Kv ∝ √Kp)", ylog=False)
    axes[5].set_yscale("log")
    rr = [r for r in recs if r["sweep"] == "rate"]
    pol = ["hold", "interpolate", "extrapolate"]
    ax = axes[6]
    for r in rr:
        yv = pol.index(r["policy"])
        ax.scatter(r["rate_hz"], yv, c=COLORS[r["outcome"]], s=40, marker="s")
        ax.annotate(f"{r['rms_error_mm']:.1f}", (r["rate_hz"], yv), fontsize=7, xytext=(0, 6), textcoords="offset points", ha="center")
    ax.set_xscale("log")
    ax.set_yticks(range(3), pol)
    ax.set_ylim(-0.5, 2.6)
    ax.set_xlabel("X_d update rate (Hz)")
    ax.set_title("X_d rate × gap policy (labels: RMS tracking error, mm)", fontsize=9)
    d = [r for r in recs if r["sweep"] == "delay"]
    ax = axes[7]
    for r in d:
        ax.scatter(max(r["delay_ticks"], 0.5), r["kp"], c=COLORS[r["outcome"]], s=40, marker="s")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("added delay (ms; 0 drawn at 0.5)")
    ax.set_ylabel("kp")
    ax.set_title("added delay × Kp (Kv ∝ √Kp)", fontsize=9)
    con = [r for r in recs if r["sweep"] == "contact"]
    for j, mode in enumerate(sorted({r["mode"] for r in con})[:4]):
        ax = axes[8 + j]
        sub = _worst_per_point([r for r in con if r["mode"] == mode])
        pushes = "/".join(f"{p:g}" for p in sorted({r["push_n"] for r in con}))
        _scatter(ax, sub, "wall_k", "wall_b", f"{mode}: its Λ and law, encoder, jitter, friction ({pushes} N, worst)",
                 ylog=True)
        for r in sub:  # Colgate's verdict point by point: a ring where the bound calls the point passive
            if r["colgate_passive"]:
                ax.scatter(r["wall_k"], r["wall_b"], s=80, facecolors="none", edgecolors="k", linewidths=0.8)
        _colgate(ax, b_tip, T, (min(CONTACT_K), max(CONTACT_K)))
        ax.axvline(3500.0, color="gray", ls=":", lw=1)
        ax.set_xlabel("stiffest part K (N/m); dotted: data sheet 3.5 N/mm")
        ax.set_ylabel("law damping B (N·s/m)")
    for ax in axes[8 + len({r["mode"] for r in con}):]:
        ax.set_visible(False)
    from vishap.robot.controller import Gains

    g = Gains()
    if len(sensors) < 2:
        axes[1].set_visible(False)
    for ax in axes[: min(2, len(sensors))]:
        ax.scatter([g.kp], [g.kv], marker="*", s=180, facecolors="none", edgecolors="k", linewidths=1.2)
    handles = [axes[0].scatter([], [], c=c, marker="s", label=k) for k, c in COLORS.items()]
    handles += axes[0].plot([], [], "k--", lw=0.8, label="Colgate–Schenkel bound b = KT/2 + |B| for the b shown")
    handles.append(axes[0].scatter([], [], marker="*", s=120, facecolors="none", edgecolors="k", label="default gains"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle(
        f"Servo stability in MuJoCo (T = {T * 1e3:g} ms). The arm's own damping b = {b_tip:.3g} N·s/m makes the "
        f"sampled wall passive only for K < {2 * b_tip / T:.0f} N/m and |B| < b (off these charts).",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.04, 1, 0.96))  # room for the legend and title (save_figure would undo it)
    import matplotlib.pyplot as plt

    path = out / "stability.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run(args) -> dict:
    from vishap.robot.params import DEFAULT
    from vishap.robot.stability import tip_damping

    t0 = time.perf_counter()
    from vishap.scale.cli import engine_args

    recs = run_sweeps(int(args.substeps), bool(args.quick), **engine_args(args))
    elapsed = time.perf_counter() - t0
    out = Path(args.out)
    b_tip = tip_damping()
    png = chart(recs, out, int(args.substeps), b_tip, DEFAULT.dt)
    counts = {k: sum(r["outcome"] == k for r in recs) for k in COLORS}
    region = stable_region(recs, int(args.substeps))
    # how often one physics step per period called a wall stable that more substeps showed was not
    walls = {(r["sensor"], r["wall_k"], r["wall_b"], r["substeps"]): r["outcome"] for r in recs if r["sweep"] == "wall"}
    hidden = sum(
        1 for (s, K, B, n), o in walls.items() if n == 1 and o == "stable" and walls.get((s, K, B, int(args.substeps)), "stable") != "stable"
    )
    return {
        "bench": "stability",
        "runs": len(recs),
        "elapsed_s": elapsed,
        "outcomes": counts,
        "substeps": int(args.substeps),
        "tip_damping_n_s_m": b_tip,
        "servo_period_s": DEFAULT.dt,
        "colgate_max_passive_stiffness_n_m": 2 * b_tip / DEFAULT.dt,
        "walls_hidden_by_one_substep": hidden,
        "stable_region": region,
        "renderable_stiffness": renderable_stiffness(recs),
        "chart": str(png),
        "machine": machine_info(),
        "records": recs,
    }
