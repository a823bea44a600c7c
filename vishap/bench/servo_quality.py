"""``vishap bench servo_quality``: what a PHANToM user would feel — force steps, buzz, speed near the
finger, touch-downs, the stiffness the device can honestly render.

1. The wall and button demos (``--seeds``, default 0–4; ``--scenes`` may add ``fabric``;
   ``--readiness`` runs issue 16 item 5's set, wall, button and fabric over seeds 0–9) are run through the public entry point
   (:func:`vishap.apps.run_demo`, as ``vishap demo SCENE --out DIR`` does) with the encoder model
   and ``--substeps`` (10) physics steps per servo period, each into ``OUT/demos/SCENE_SEED``; a
   folder that already holds a ``summary.json`` is read, not run again (``--logs DIR`` reads
   ``DIR/SCENE_SEED`` instead). :func:`read_log` is the one place that knows the log's channels.
2. From each log: saturated ticks and the largest per-tick force step outside contact; Λ changes per
   approach; the command's ripple in still holds, approaches and contact (spectra); the device's
   speed within 20 mm of the finger; make/break count and normal device speed at each touch-down;
   whether the device was ready at each touch (:func:`vishap.world.closed_loop.device_ready`, the
   conditions ``bench world`` counts), summed per scene as ``demo_ready_touches``.

   A *hold* (``hold_ripple_n_rms``, ``hold_ripple_above_30hz_n_rms``) is the issue's still hold: the
   servo's target still (moved < 0.1 mm over 100 ms) outside contact, and the device itself arrived
   and still over the same 100 ms — within ``HOLD_ARRIVED_M`` of the target and slower than
   ``HOLD_STILL_M_S``. The target-only definition used before (most of whose figure was the device
   still travelling into a target that had stopped: 0.67 N rms in button seed 1's first move) stays
   beside it as ``still_target_ripple_n_rms`` and ``still_target_ripple_above_30hz_n_rms``.
3. The servo alone, holding still and following a 30 Hz target at 0.1 m/s (the same plant, encoder
   and substeps), with the shipped gains and with the gains before issue 16 side by side: ripple and
   the *true* tip vibration (the demo logs carry only the encoder's position).
4. ``max_stable_stiffness_n_m``: the stiffest law the demos' modes may render at their damping
   (``vishap/robot/gains.yaml``, measured by ``vishap bench stability``'s contact sweep).

Writes ``servo_quality.json`` (via the command) and ``servo_quality.png``.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "force steps, buzz, speed near the finger and touch-downs in the wall/button demos; honest stiffness"

SCENES = ("wall", "button")
#: the scenes a run may name (issue 16 item 5 counts ready touches in all three)
ALL_SCENES = ("wall", "button", "fabric")
#: ``--readiness``: issue 16 item 5's demos with real vision
READINESS_SCENES, READINESS_SEEDS = ALL_SCENES, tuple(range(10))
#: a hold needs the device itself arrived: this close to the still target (the readiness condition's
#: 0.5 mm on the face), …
HOLD_ARRIVED_M = 0.0005
#: … and still (readiness: 10 mm/s; one encoder count reads ≤ 5.4 mm/s in the ±3-tick difference)
HOLD_STILL_M_S = 0.010
NEAR_M = 0.020  # "near the finger"
TOUCH_WINDOW_S = 0.100  # make/break counted over the first 100 ms of a touch
HI_HZ = 30.0  # the vision rate: ripple above it is buzz, not motion
#: the gains before issue 16 (backward-difference velocity, no vision-rate filter), for the side-by-side
OLD_GAINS = {"kp": 800.0, "kv": 32.0, "a": 500.0, "velocity_hz": 0.0, "vision_hz": 0.0}


def add_arguments(parser) -> None:
    parser.add_argument("--seeds", default="0,1,2,3,4", help="demo seeds (default 0,1,2,3,4)")
    parser.add_argument("--scenes", default=",".join(SCENES), help=f"demos to run, from {','.join(ALL_SCENES)} (default wall,button)")
    parser.add_argument("--readiness", action="store_true",
                        help="issue 16 item 5's set: wall, button and fabric, seeds 0-9 (overrides --scenes/--seeds)")
    parser.add_argument("--substeps", type=int, default=10, help="physics steps per servo period (default 10)")
    parser.add_argument("--logs", default=None, help="read demo outputs DIR/SCENE_SEED instead of running them")
    parser.add_argument("--seconds", type=float, default=2.0, help="length of the servo-alone runs (default 2)")
    from vishap.scale.cli import add_engine_options

    add_engine_options(parser, sweep=True)


# -- the one place that knows the log --------------------------------------------------------------
def read_log(folder) -> dict:
    """The channels this bench needs from a demo's ``log.npz`` (+ ``summary.json``), by name.

    Returns SI arrays: ``t`` (s), ``F_cmd`` (N, n×3), ``saturated``, ``in_contact`` (the finger
    touches the device), ``law_active``, ``guard`` (0 track, 1 hold, 2 retreat), ``p_device`` (m,
    the encoder's), ``p_finger`` (m, the true finger pad), ``device_depth`` (m under the subject's
    surface), ``X_d`` (m) and ``lambda_state`` (0 free, 1 surface, 2 engaged: logged by a servo that
    schedules Λ, otherwise inferred the way the demo loop sets Λ from depth and ``engage_m``)."""
    folder = Path(folder)
    with np.load(folder / "log.npz", allow_pickle=False) as z:
        g = {k: z[k] for k in z.files if k.startswith("servo/")}
    summary = json.loads((folder / "summary.json").read_text())
    s = lambda name: g[f"servo/{name}"]  # noqa: E731 - a local shorthand
    law = s("law_active").astype(bool)
    depth = s("device_depth").astype(float)
    if "servo/lambda_state" in g:
        lam = s("lambda_state").astype(int)
    else:  # the demo loop before the scheduler: surface while the law acts, engaged past engage_m
        import inspect

        from vishap.world.world import World

        engage = float(inspect.signature(World).parameters["engage_m"].default)
        lam = np.where(law, np.where(depth > engage, 2, 1), 0)
    return {
        "t": s("t").astype(float), "F_cmd": s("F_cmd").astype(float), "saturated": s("saturated").astype(bool),
        "in_contact": s("in_contact").astype(bool), "law_active": law, "guard": s("guard").astype(int),
        "p_device": s("device_point").astype(float), "p_finger": s("finger_point").astype(float),
        "device_depth": depth, "finger_depth": s("finger_depth").astype(float) if "servo/finger_depth" in g else None,
        "X_d": s("X_d").astype(float), "lambda_state": lam, "summary": summary,
    }


# -- measures ---------------------------------------------------------------------------------------
def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _velocity(p: np.ndarray, dt: float, half: int = 3) -> np.ndarray:
    """Central difference over ±``half`` ticks (the encoder's 30 µm steps would make a one-tick
    difference read 30 mm/s at rest)."""
    v = np.zeros_like(p)
    v[half:-half] = (p[2 * half:] - p[: -2 * half]) / (2 * half * dt)
    return v


def _segments_rms(F: np.ndarray, segs, fs: float, lo: float) -> tuple[float, int]:
    """Power-weighted RMS above ``lo`` Hz over segments (each ≥ 100 ticks), and the ticks used."""
    num, n = 0.0, 0
    from vishap.robot.tracking import band_rms

    for a, b in segs:
        if b - a >= 100:
            r = band_rms(F[a:b], fs, lo)
            num += r * r * (b - a)
            n += b - a
    return (math.sqrt(num / n) if n else float("nan")), n


def _window_all(ok: np.ndarray, dt: float, win_s: float = 0.1) -> np.ndarray:
    """Ticks whose surrounding ``win_s`` (centred, as :func:`_still`'s) holds ``ok`` throughout."""
    from scipy.ndimage import minimum_filter1d

    w = max(1, int(win_s / dt / 2))
    out = minimum_filter1d(ok.astype(np.uint8), size=2 * w + 1, mode="constant", cval=0).astype(bool)
    return out


def _arrived(p: np.ndarray, X_d: np.ndarray, speed: np.ndarray, dt: float) -> np.ndarray:
    """Ticks around which (over :func:`_still`'s window) the device is within ``HOLD_ARRIVED_M`` of its
    target and slower than ``HOLD_STILL_M_S``: the device itself holds still."""
    err = np.linalg.norm(X_d - p, axis=1)
    ok = np.isfinite(err) & (err <= HOLD_ARRIVED_M) & (speed <= HOLD_STILL_M_S)
    return _window_all(ok, dt)


def ready_touches(log: dict, scene: str) -> list[dict]:
    """Each touch of a demo log and whether the device was ready for it, by
    :func:`vishap.world.closed_loop.device_ready` (and each condition, ``ready_checks``).

    A touch is the first tick at which the finger touches the device or reaches the virtual surface
    (as ``bench world`` counts it), after at least ``TOUCH_WINDOW_S`` of neither. The scene's first
    object and passive face come from its scene file (as the demo builds them); device and finger
    velocities are the ±3-tick central difference of the logged points (the device's encoder point,
    the finger's pad)."""
    from vishap.world.closed_loop import device_ready, ready_checks
    from vishap.world.scene import load_scene

    if log["finger_depth"] is None:
        return []
    sc = load_scene(scene)
    obj, half = sc.objects[0], float(sc.passive_object.half_size_m)
    t = log["t"]
    dt = float(np.median(np.diff(t)))
    p, pf = log["p_device"], log["p_finger"]
    v, vf = _velocity(p, dt), _velocity(np.nan_to_num(pf), dt)
    touching = log["in_contact"] | (np.nan_to_num(log["finger_depth"], nan=-np.inf) >= 0.0)
    out, last_end = [], -math.inf
    for a, b in _runs(touching):
        if t[a] - last_end >= TOUCH_WINDOW_S:
            args = (obj, p[: a + 1], v[: a + 1], pf[a], vf[: a + 1], half, dt)
            out.append({"t_s": float(t[a]), "ready": bool(device_ready(*args)), "checks": ready_checks(*args)})
        last_end = t[b - 1]
    return out


def _still(X_d: np.ndarray, dt: float, win_s: float = 0.1, tol_m: float = 1e-4) -> np.ndarray:
    """Ticks at which the servo's target moved less than ``tol_m`` over the surrounding ``win_s``."""
    n = len(X_d)
    w = max(1, int(win_s / dt / 2))
    ok = np.isfinite(X_d).all(axis=1)
    Xf = np.where(ok[:, None], X_d, 0.0)
    still = np.zeros(n, dtype=bool)
    for i in range(w, n - w):
        seg = Xf[i - w: i + w + 1]
        still[i] = ok[i - w: i + w + 1].all() and float(np.max(np.ptp(seg, axis=0))) < tol_m
    return still


def analyse(log: dict) -> dict:
    """Every per-demo figure of the bench from one :func:`read_log` record."""
    t, F = log["t"], log["F_cmd"]
    dt = float(np.median(np.diff(t)))
    fs = 1.0 / dt
    contact = log["in_contact"] | log["law_active"]
    out_c = ~contact
    dF = np.linalg.norm(np.diff(F, axis=0), axis=1)
    both_out = out_c[1:] & out_c[:-1]
    p, pf = log["p_device"], log["p_finger"]
    v = _velocity(p, dt)
    speed = np.linalg.norm(v, axis=1)
    dist = np.linalg.norm(p - pf, axis=1)
    near = (dist < NEAR_M) & ~log["in_contact"] & np.isfinite(dist)
    # touches: runs of contact; a touch = the first make after ≥ 100 ms out of contact
    touches = []
    last_end = -math.inf
    ic = log["in_contact"]
    vn = _velocity(log["device_depth"][:, None], dt)[:, 0]  # normal speed, + into the surface
    for a, b in _runs(ic):
        if t[a] - last_end >= TOUCH_WINDOW_S:
            w = (t >= t[a]) & (t < t[a] + TOUCH_WINDOW_S)
            makes = int(np.count_nonzero(np.diff(ic[w].astype(np.int8)) == 1)) + 1
            touches.append({"t_s": float(t[a]), "makes_in_100ms": makes, "device_normal_speed_mm_s": float(abs(vn[a]) * 1e3)})
        last_end = t[b - 1]
    # approaches: from the first free Λ after the previous touch's contact ended (the start of the
    # log for the first) to 200 ms after this touch — the release belongs to the touch before
    lam = log["lambda_state"]
    lam_changes = np.flatnonzero(np.diff(lam) != 0) + 1
    ends = [t[b - 1] for _, b in _runs(ic)]
    per_approach, per_cycle = [], []
    t_ch = t[lam_changes]

    def free_after(end: float) -> float:
        """The first free Λ after a contact that ended at ``end`` (the end of the log if none)."""
        k = np.flatnonzero((t > end) & (lam == 0))
        return float(t[k[0]]) if k.size else math.inf

    for i, tc in enumerate(touches):
        prev = [e for e in ends if e < tc["t_s"]]
        lo = free_after(prev[-1]) if prev else -math.inf
        lo = min(lo, tc["t_s"])
        hi = tc["t_s"] + 0.2
        per_approach.append(int(np.count_nonzero((t_ch > lo) & (t_ch <= hi))))
        # the whole cycle: this approach, the press and its release, up to the first free Λ after
        # the last contact before the next touch (a full cycle is free → surface → engaged → surface → free)
        nxt = touches[i + 1]["t_s"] if i + 1 < len(touches) else math.inf
        mine = [e for e in ends if tc["t_s"] <= e < nxt]
        end = free_after(mine[-1]) if mine else math.inf
        per_cycle.append(int(np.count_nonzero((t_ch > lo) & (t_ch <= end))))
    still = _still(log["X_d"], dt) & out_c & (log["guard"] != 2)
    hold = still & _arrived(p, log["X_d"], speed, dt)
    moving = out_c & ~still & (speed > 0.02)
    hold_segs, appr_segs, cont_segs = _runs(hold), _runs(moving), _runs(log["in_contact"])
    target_segs = _runs(still)
    hold_all, n_hold = _segments_rms(F, hold_segs, fs, 0.0)
    hold_hi, _ = _segments_rms(F, hold_segs, fs, HI_HZ)
    tgt_all, n_tgt = _segments_rms(F, target_segs, fs, 0.0)
    tgt_hi, _ = _segments_rms(F, target_segs, fs, HI_HZ)
    appr_hi, n_appr = _segments_rms(F, appr_segs, fs, HI_HZ)
    cont_hi, n_cont = _segments_rms(F, cont_segs, fs, HI_HZ)
    return {
        "saturated_ticks_outside_contact": int(np.count_nonzero(log["saturated"] & out_c)),
        "max_force_step_outside_contact_n": float(dF[both_out].max()) if both_out.any() else 0.0,
        "force_steps_over_0_5n_outside_contact": int(np.count_nonzero(dF[both_out] > 0.5)),
        "lambda_changes": int(len(lam_changes)),
        "lambda_changes_per_approach": per_approach, "lambda_changes_per_touch_cycle": per_cycle,
        "hold_ripple_n_rms": hold_all, "hold_ripple_above_30hz_n_rms": hold_hi, "hold_ticks": n_hold,
        "still_target_ripple_n_rms": tgt_all, "still_target_ripple_above_30hz_n_rms": tgt_hi, "still_target_ticks": n_tgt,
        "approach_ripple_above_30hz_n_rms": appr_hi, "approach_ticks": n_appr,
        "contact_ripple_above_30hz_n_rms": cont_hi, "contact_ticks": n_cont,
        "device_speed_near_finger_max_m_s": float(speed[near].max()) if near.any() else 0.0,
        # when: the moment to read the finger estimate's error at (docs/robot.md, "speed near the finger")
        "device_speed_near_finger_max_t_s": float(t[near][np.argmax(speed[near])]) if near.any() else None,
        "time_faster_than_0_1_m_s_near_finger_ms": float(np.count_nonzero(near & (speed > 0.1)) * dt * 1e3),
        "touches": touches,
        "force_depth_r2": log["summary"].get("force_depth_r2"),
        "_spectra": {k: _spectrum(F, segs, fs) for k, segs in (("hold", hold_segs), ("approach", appr_segs), ("contact", cont_segs))},
        "_trace": {"t": t, "lambda_state": lam, "F": np.linalg.norm(F, axis=1), "speed": speed, "dist": dist, "near": near},
    }


def _spectrum(F, segs, fs, n: int = 256):
    """Mean one-sided amplitude spectrum (N/√Hz-like, Welch with ``n``-tick windows) over segments."""
    acc, k = None, 0
    win = np.hanning(n)
    for a, b in segs:
        for s0 in range(a, b - n + 1, n // 2):
            x = F[s0: s0 + n] - F[s0: s0 + n].mean(axis=0)
            P = np.sum(np.abs(np.fft.rfft(x * win[:, None], axis=0)) ** 2, axis=1)
            acc = P if acc is None else acc + P
            k += 1
    if not k:
        return None
    return np.fft.rfftfreq(n, 1.0 / fs), np.sqrt(acc / k * 2.0 / (fs * np.sum(win**2)))


def servo_alone(gains, seconds: float, substeps: int) -> dict:
    """Hold and 30 Hz approach of the servo alone: ripple (N rms) and true tip vibration (µm rms)."""
    from vishap.robot.tracking import band_rms, hold_and_approach

    h = hold_and_approach(gains, "hold", seconds=seconds, substeps=substeps)
    a = hold_and_approach(gains, "approach", seconds=seconds, substeps=substeps)
    return {
        "hold_ripple_n_rms": band_rms(h["F"], 1000.0), "hold_ripple_above_30hz_n_rms": band_rms(h["F"], 1000.0, HI_HZ),
        "tip_vibration_above_30hz_um_rms": band_rms(h["p"], 1000.0, HI_HZ) * 1e6,
        "approach_ripple_above_30hz_n_rms": band_rms(a["F"], 1000.0, HI_HZ),
    }


def _demo_folders(args, out: Path) -> list[tuple[str, int, Path]]:
    from vishap._core.errors import ConfigError

    try:
        seeds = [int(s) for s in str(args.seeds).split(",") if s.strip()]
    except ValueError:
        raise ConfigError(f"expected comma-separated integers, got {args.seeds!r}", field="--seeds") from None
    scenes = [s.strip() for s in str(args.scenes).split(",") if s.strip()]
    if getattr(args, "readiness", False):
        scenes, seeds = list(READINESS_SCENES), list(READINESS_SEEDS)
    bad = [s for s in scenes if s not in ALL_SCENES]
    if bad or not scenes or not seeds:
        raise ConfigError(f"expected scenes from {ALL_SCENES} and at least one seed, got {args.scenes!r} / {args.seeds!r}",
                          field="--scenes")
    base = Path(args.logs) if args.logs else out / "demos"
    folders, todo = [], []
    for scene in scenes:
        for seed in seeds:
            d = base / f"{scene}_{seed}"
            if not (d / "summary.json").is_file():
                if args.logs:
                    raise ConfigError(f"no demo output in {d} (expected log.npz and summary.json)", field="--logs")
                todo.append((d.name, {"scene": scene, "seed": seed, "substeps": int(args.substeps), "encoder": "encoder",
                                      "video": False, "save_frames": False}))
            folders.append((scene, seed, d))
    # the demos as Ray tasks with --workers/--address; their files come back and are written here
    from vishap.scale import map_cases
    from vishap.scale.cli import engine_args
    from vishap.scale.folders import commit_files

    ran = map_cases(demo_files, [fields for _, fields in todo], desc="demos", **engine_args(args))
    for (name, _), files in zip(todo, ran):
        commit_files(base, name, files)
    return folders


def _worst_near(demos: list[dict]) -> dict | None:
    """Where the device was fastest near the finger: ``{scene, seed, t_s, m_s}`` (None without demos)."""
    if not demos:
        return None
    d = max(demos, key=lambda d: d["device_speed_near_finger_max_m_s"])
    return {"scene": d["scene"], "seed": d["seed"], "t_s": d["device_speed_near_finger_max_t_s"],
            "m_s": d["device_speed_near_finger_max_m_s"]}


def demo_files(fields: dict) -> dict[str, bytes]:
    """One demo (``DemoConfig`` fields) run into a temporary folder: its files, by relative path."""
    import tempfile

    from vishap.apps import DemoConfig, run_demo
    from vishap.scale.folders import read_files

    with tempfile.TemporaryDirectory(prefix="vishap-demo-") as tmp:
        run_demo(DemoConfig(**fields), Path(tmp) / "demo")
        return read_files(Path(tmp) / "demo")


def _stiffness() -> dict:
    from vishap.robot.gains import max_renderable_stiffness
    from vishap.world.modes import default_modes

    db = default_modes()
    per = {name: max_renderable_stiffness(db.modes[name].law.damping_n_s_m) for name in ("hard_wall", "key_click")}
    return {"max_stable_stiffness_n_m": min(per.values()), "max_stable_stiffness_by_mode_n_m": per}


def _ready_by_scene(demos: list[dict]) -> dict:
    """``{scene: {"ready": n, "touches": n}}`` over the demos' touches."""
    out: dict = {}
    for d in demos:
        r = out.setdefault(d["scene"], {"ready": 0, "touches": 0})
        r["ready"] += sum(tc["ready"] for tc in d["ready_touches"])
        r["touches"] += len(d["ready_touches"])
    return out


def chart(demos: list[dict], alone: dict, out: Path) -> Path:
    fig, axes = new_figure(2, 4, figsize=(22, 9))
    ax = axes[0, 0]
    for kind, color in (("hold", "tab:blue"), ("approach", "tab:orange"), ("contact", "tab:green")):
        specs = [d["_spectra"][kind] for d in demos if d["_spectra"][kind] is not None]
        if specs:
            f = specs[0][0]
            ax.loglog(f[1:], np.mean([s[1] for s in specs], axis=0)[1:], color=color, label=kind)
    ax.axvline(HI_HZ, color="k", ls=":", lw=0.8)
    ax.set_xlabel("Hz")
    ax.set_ylabel("|F_cmd| spectrum (N/√Hz)")
    ax.set_title("command spectrum in the demos (mean over demos)", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    d0 = demos[0]["_trace"]
    ax.plot(d0["t"], d0["lambda_state"], lw=0.8)
    ax.set_yticks([0, 1, 2], ["free", "surface", "engaged"])
    ax.set_xlabel("t (s)")
    ax.set_title(f"Λ state, {demos[0]['scene']} seed {demos[0]['seed']} ({demos[0]['lambda_changes']} changes)", fontsize=9)
    ax2 = ax.twinx()
    ax2.plot(d0["t"], d0["F"], color="tab:red", lw=0.5, alpha=0.6)
    ax2.set_ylabel("|F_cmd| (N)", color="tab:red")
    ax = axes[0, 2]
    for d in demos:
        tr = d["_trace"]
        m = np.isfinite(tr["dist"]) & (tr["dist"] < 0.1)
        ax.scatter(tr["dist"][m] * 1e3, tr["speed"][m], s=1, alpha=0.2)
    ax.axvline(NEAR_M * 1e3, color="k", ls=":", lw=0.8)
    ax.axhline(0.25, color="tab:red", ls="--", lw=0.8, label="goal ≤ 0.25 m/s within 20 mm")
    ax.set_xlabel("device–finger distance (mm)")
    ax.set_ylabel("device speed (m/s)")
    ax.set_title("speed near the finger (all demos)", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[1, 0]
    tds = [tc for d in demos for tc in d["touches"]]
    if tds:
        ax.scatter([tc["device_normal_speed_mm_s"] for tc in tds], [tc["makes_in_100ms"] for tc in tds], s=25)
    ax.axvline(10.0, color="tab:red", ls="--", lw=0.8)
    ax.axhline(1.0, color="tab:red", ls="--", lw=0.8)
    ax.set_xlabel("device normal speed at the touch (mm/s)")
    ax.set_ylabel("makes in the first 100 ms")
    ax.set_title("touch-downs (goal: ≤ 10 mm/s, 1 make)", fontsize=9)
    ax = axes[1, 1]
    keys = ["hold_ripple_n_rms", "hold_ripple_above_30hz_n_rms", "approach_ripple_above_30hz_n_rms"]
    x = np.arange(len(keys))
    ax.bar(x - 0.2, [alone["before"][k] for k in keys], 0.4, label="gains before")
    ax.bar(x + 0.2, [alone["shipped"][k] for k in keys], 0.4, label="shipped gains")
    ax.set_xticks(x, ["hold", "hold >30 Hz", "approach >30 Hz"])
    ax.set_yscale("log")
    ax.set_ylabel("N rms")
    ax.set_title("servo alone (encoder, same plant): ripple", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[1, 2]
    ax.bar([0, 1], [alone["before"]["tip_vibration_above_30hz_um_rms"], alone["shipped"]["tip_vibration_above_30hz_um_rms"]])
    ax.axhline(2.0, color="tab:red", ls="--", lw=0.8)
    ax.set_xticks([0, 1], ["gains before", "shipped gains"])
    ax.set_ylabel("µm rms above 30 Hz")
    ax.set_title("true tip vibration in a still hold", fontsize=9)
    ready = _ready_by_scene(demos)
    ax = axes[0, 3]
    names = list(ready)
    ax.bar(names, [ready[n]["touches"] for n in names], color="lightgrey", label="touches")
    ax.bar(names, [ready[n]["ready"] for n in names], color="tab:green", label="device ready")
    ax.set_ylabel("touches")
    ax.set_title("device ready at the touch (device_ready; goal ≥ 9 of 10)", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[1, 3]
    conds = ["still_normal", "still_tangential", "face", "inside"]
    x = np.arange(len(conds))
    for i, n in enumerate(names):
        tcs = [tc for d in demos if d["scene"] == n for tc in d["ready_touches"]]
        ax.bar(x + (i - (len(names) - 1) / 2) * 0.8 / max(len(names), 1),
               [np.mean([tc["checks"][c] for tc in tcs]) if tcs else 0.0 for c in conds], 0.8 / max(len(names), 1), label=n)
    ax.set_xticks(x, conds, fontsize=8)
    ax.set_ylabel("share of touches meeting it")
    ax.set_title("readiness conditions per scene", fontsize=9)
    ax.legend(fontsize=8)
    return save_figure(fig, out / "servo_quality.png")


def run(args) -> dict:
    from vishap.robot.controller import Gains
    from vishap.robot.gains import load_gains

    t0 = time.perf_counter()
    out = Path(args.out)
    folders = _demo_folders(args, out)
    demos = []
    for scene, seed, d in folders:
        log = read_log(d)
        rec = analyse(log)
        rec.update(scene=scene, seed=seed, folder=str(d), ready_touches=ready_touches(log, scene))
        demos.append(rec)
    shipped, _ = load_gains()
    alone = {"shipped": servo_alone(shipped, args.seconds, int(args.substeps)),
             "before": servo_alone(Gains(**OLD_GAINS), args.seconds, int(args.substeps))}
    png = chart(demos, alone, out)
    touches = [tc for d in demos for tc in d["touches"]]
    nan_max = lambda xs: float(np.nanmax(xs)) if len(xs) and np.any(np.isfinite(xs)) else None  # noqa: E731
    res = {
        "bench": "servo_quality",
        "demos": len(demos), "substeps": int(args.substeps), "sensor": "encoder",
        "saturated_ticks_outside_contact": int(sum(d["saturated_ticks_outside_contact"] for d in demos)),
        "max_force_step_outside_contact_n": nan_max([d["max_force_step_outside_contact_n"] for d in demos]),
        "lambda_changes_per_approach_max": max((c for d in demos for c in d["lambda_changes_per_approach"]), default=0),
        "lambda_changes_per_touch_cycle_max": max((c for d in demos for c in d["lambda_changes_per_touch_cycle"]), default=0),
        "hold_ripple_n_rms": nan_max([d["hold_ripple_n_rms"] for d in demos]),
        "hold_ripple_above_30hz_n_rms": nan_max([d["hold_ripple_above_30hz_n_rms"] for d in demos]),
        "still_target_ripple_n_rms": nan_max([d["still_target_ripple_n_rms"] for d in demos]),
        "still_target_ripple_above_30hz_n_rms": nan_max([d["still_target_ripple_above_30hz_n_rms"] for d in demos]),
        "approach_ripple_above_30hz_n_rms": nan_max([d["approach_ripple_above_30hz_n_rms"] for d in demos]),
        "device_speed_near_finger_max_m_s": nan_max([d["device_speed_near_finger_max_m_s"] for d in demos]),
        "device_speed_near_finger_max_at": _worst_near(demos),
        "touch_make_break_max": max((tc["makes_in_100ms"] for tc in touches), default=0),
        "touch_device_speed_mm_s_max": max((tc["device_normal_speed_mm_s"] for tc in touches), default=0.0),
        "tip_vibration_above_30hz_um_rms": alone["shipped"]["tip_vibration_above_30hz_um_rms"],
        **_stiffness(),
        "demo_ready_touches": _ready_by_scene(demos),
        "scenes": sorted({d["scene"] for d in demos}), "seeds": sorted({d["seed"] for d in demos}),
        "servo_alone": alone,
        "per_demo": [{k: v for k, v in d.items() if not k.startswith("_")} for d in demos],
        "elapsed_s": time.perf_counter() - t0,
        "chart": str(png),
        "machine": machine_info(),
        "notes": "maxima over demos; hold/approach ripple from the demo logs (F_cmd), tip vibration from the servo "
                 "alone (true MuJoCo position: the logs carry the encoder's); hold = target still and the device "
                 f"within {HOLD_ARRIVED_M * 1e3:g} mm of it and slower than {HOLD_STILL_M_S * 1e3:g} mm/s over 100 ms "
                 "(still_target_* = the target still only, the definition before); demo_ready_touches by "
                 "vishap.world.closed_loop.device_ready",
    }
    return res
