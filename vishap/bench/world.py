"""``vishap bench world``: the encountered-type meeting in closed loop (VisHap §2.2–2.3, Fig. 6).

A simulated finger (noisy, late, 30 Hz fingertip samples) approaches the objects of each scene at
peak speeds 0.1–0.5 m/s, meets the MuJoCo PHANToM behind the demos' own servo side
(:func:`vishap.apps.assemble.make_servo_side`, ``settings.servo``), presses, slides and leaves. The record holds:

* ``device_in_place_rate`` — share of approaches where the device was within ``in_place_mm`` of the
  ideal contact point when the finger touched; ``contact_lead_time_ms_*`` — how long it had been
  there; ``contact_position_error_mm`` — its distance from that point at the touch;
* ``device_ready_rate`` — share of approaches where the device was *ready* at the touch (issue 16:
  for 20 ms before it still along the normal, ≤ 10 mm/s, and ≤ 20 mm/s sideways relative to the
  finger; its face within 0.5 mm of the virtual surface; the finger landing ≥ 10 mm inside the
  face's edge; :func:`vishap.world.closed_loop.device_ready`), per speed as ``ready_rate``, and the
  share meeting each condition as ``ready_checks_rate`` (a face narrower than 20 mm never meets ``inside``);
* Fig. 6: ``wall_force_depth_r2`` (straight line of force against fingertip depth, pooled over
  the wall presses) and ``button_click_detected`` (two slopes and a force drop), with plots;
* ``multi_object`` — the panel scene: subject at the touch, cuts through other objects;
* ``servo_cost_us`` per scene — the force law alone and a whole servo tick with it, beside a
  tick without any law (the wall must not pay for button or fabric machinery);
* ``policies`` — prediction/handover policies on the same approaches (one chart);
* ``sensitivity`` — the same wall approaches with better fingertip data (60 Hz / 20 ms, no noise,
  an ideal 250 Hz camera) and with the truth given to the world: the touch point from the start or
  100 ms before the touch (``perfect_prediction*``: the device waits there still), and the finger's
  own path (``perfect_path``: the run-up exact — the bound on readiness the servo side allows).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, median_us, new_figure, save_figure, time_calls

HELP = "world: closed-loop meeting on the MuJoCo device (lead, contact error, Fig. 6), policies, servo cost"

#: (predictor, handover, contact model) on the system's servo step (the demos': gains file, guard, travel limiter);
#: ``both`` is the system's (:class:`vishap.apps.config.DemoConfig`), ``all`` the world's own default
POLICIES = [
    ("none", "track", "ray"),
    ("cv", "hold", "ray"),
    ("kalman", "hold", "ray"),
    ("kalman", "hold", "path"),
    ("kalman", "hold", "reach"),
    ("kalman", "hold", "both"),
    ("kalman", "hold", "all"),
]


def _system_contact_model() -> str:
    from vishap.apps.config import DemoConfig

    return DemoConfig.model_fields["contact_model"].default


def _servo_settings() -> dict:
    """The servo side the closed loop runs: the demos' (``apps.assemble.make_servo_side`` from the
    default :class:`~vishap.apps.config.DemoConfig`)."""
    from vishap.apps.config import DemoConfig

    cfg = DemoConfig()
    return {"assembly": "vishap.apps.assemble.make_servo_side (as the demos and live mode)",
            "travel": "TravelLimiter.for_approach", "travel_speed_m_s": cfg.travel_speed_m_s,
            "travel_accel_m_s2": cfg.travel_accel_m_s2, "joint_sensor": cfg.encoder, "substeps": cfg.substeps,
            "target_policy": cfg.servo_policy}


def add_arguments(p) -> None:
    p.add_argument("--approaches", type=int, default=20, help="approaches per scene (default 20)")
    p.add_argument("--policy-approaches", type=int, default=40, help="approaches per policy (wall scene)")
    p.add_argument("--scenes", default="wall,button,fabric,panel", help="comma-separated scenes")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--rate-hz", type=float, default=30.0, help="fingertip sample rate")
    p.add_argument("--latency-ms", type=float, default=33.0, help="fingertip sample latency")
    p.add_argument("--noise-mm", type=float, default=0.3, help="fingertip noise σ per axis")
    p.add_argument("--dropout", type=float, default=0.05, help="share of lost fingertip samples")
    p.add_argument("--bow", type=float, default=0.10, help="largest sideways bow of a path, share of its length")
    p.add_argument("--in-place-mm", type=float, default=1.0)
    from vishap.scale.cli import add_engine_options

    add_engine_options(p, sweep=True)


def _pct(x, q):
    x = np.asarray([v for v in x if v is not None], dtype=float)
    return float(np.percentile(x, q)) if x.size else None


def _summary(results, in_place_m):
    err = [r.contact_error_m * 1e3 for r in results if r.contact_error_m is not None]
    leads = [r.lead_time_s * 1e3 for r in results if r.lead_time_s is not None]
    speeds = sorted({r.speed_m_s for r in results})
    by_speed = {}
    for s in speeds:
        rs = [r for r in results if r.speed_m_s == s]
        e = [r.contact_error_m * 1e3 for r in rs if r.contact_error_m is not None]
        by_speed[f"{s:.1f}"] = {
            "approaches": len(rs),
            "in_place_rate": float(np.mean([r.in_place for r in rs])),
            "ready_rate": float(np.mean([r.ready for r in rs])),
            "error_mm_median": _pct(e, 50),
            "error_mm_max": max(e) if e else None,
        }
    return {
        "approaches": len(results),
        "device_in_place_rate": float(np.mean([r.in_place for r in results])) if results else None,
        "device_ready_rate": float(np.mean([r.ready for r in results])) if results else None,
        "ready_checks_rate": {k: float(np.mean([r.ready_checks.get(k, False) for r in results]))
                              for k in ("still_normal", "still_tangential", "face", "inside")} if results else None,
        "device_in_place_rate_2mm": float(np.mean([r.contact_error_m is not None and r.contact_error_m <= 0.002 for r in results])),
        "touched_passive_object_rate": float(np.mean([r.touched for r in results])),
        "contact_lead_time_ms_min": min(leads) if leads else None,
        "contact_lead_time_ms_median": _pct(leads, 50),
        "contact_position_error_mm": {"median": _pct(err, 50), "p95": _pct(err, 95), "max": max(err) if err else None},
        "by_speed_m_s": by_speed,
    }


def _brief(rs, trajs, in_place_m):
    sm = _summary(rs, in_place_m)
    out = {k: sm[k] for k in ("device_in_place_rate", "device_ready_rate", "contact_position_error_mm", "contact_lead_time_ms_min",
                              "ready_checks_rate")}
    straight = [r.in_place for r, tr in zip(rs, trajs) if abs(tr.bow_m) < 0.002]
    out["straight_paths_in_place_rate"] = float(np.mean(straight)) if straight else None
    return out


def _line_fit(d, f):
    slope, icpt = np.polyfit(d, f, 1)
    res = f - (slope * d + icpt)
    return float(slope), float(icpt), float(1.0 - res.var() / f.var())


def _click(d, f):
    """Two slopes and a drop on one press-in: (k_resist, k_click, drop share) in finger depth."""
    grow = np.r_[True, np.diff(d) > 0]
    d, f = d[grow], f[grow]
    m = (d > 0) & (d < 0.0035)
    if m.sum() < 20:
        return None
    i_pk = int(np.argmax(np.where(m, f, -np.inf)))
    d_pk, f_pk = d[i_pk], f[i_pk]
    after = (d > d_pk) & (d < d_pk + 0.0008)
    if not after.any():
        return None
    i_lo = np.nonzero(after)[0][int(np.argmin(f[after]))]
    drop = 1.0 - f[i_lo] / f_pk
    b = (d > 0.0003) & (d < 0.8 * d_pk)
    a = (d > d[i_lo] + 0.0002) & (d < d[i_lo] + 0.0012)
    if b.sum() < 5 or a.sum() < 5:
        return None
    return float(np.polyfit(d[b], f[b], 1)[0]), float(np.polyfit(d[a], f[a], 1)[0]), float(drop)


def _servo_cost(scenes, rounds=5, n=3000):
    """Median µs of the force law alone and of a whole servo step with it, per scene (interleaved),
    beside a servo step without a law (no subject)."""
    from vishap.robot import kinematics
    from vishap.runtime.core import TargetRecord
    from vishap.world.closed_loop import make_device

    setups = {}
    for name, scene in scenes.items():
        obj = scene.objects[0]
        step = make_device(scene)
        p_in = obj.centre - obj.normal * 0.001  # the device's contact point, pressed 1 mm in
        X_ee = tuple(p_in - step.mount)
        step.device.reset(kinematics.ik(np.asarray(X_ee)))
        v = np.array([0.01, 0.0, -0.01])
        law_rec = TargetRecord(1, X_ee, 0.0, 1.0, True, True, 0, True, True)
        free_rec = TargetRecord(1, X_ee, 0.0, 1.0, True, True, -1, False, False)
        setups[name] = (step, p_in, v, law_rec, free_rec)
    out = {k: {"law": [], "tick_with_law": []} for k in setups}
    free = []
    for _ in range(rounds):
        for name, (step, p_in, v, law_rec, _) in setups.items():
            law = step.contact.laws[0]
            out[name]["law"].append(median_us(time_calls(lambda: law.force_robot(p_in, v), n)))
            t = [0.0]

            def tick():
                t[0] += 0.001
                law_rec.made_at = t[0]
                step.tick(t[0], law_rec)

            out[name]["tick_with_law"].append(median_us(time_calls(tick, n)))
        step0, _, _, _, free_rec = next(iter(setups.values()))
        t0 = [0.0]

        def tick_free():
            t0[0] += 0.001
            free_rec.made_at = t0[0]
            step0.tick(t0[0], free_rec)

        free.append(median_us(time_calls(tick_free, n)))
    rec = {k: {kk: float(np.median(vv)) for kk, vv in d.items()} for k, d in out.items()}
    for name, (step, *_rest) in setups.items():
        rec[name]["laws"] = sorted({type(law).__name__ for law in step.contact.laws})
    rec["tick_without_law"] = float(np.median(free))
    return rec


def _perfect_world_class():
    from vishap.world.world import World

    class PerfectWorld(World):
        """The world with perfect prediction: X_d is the true touch point of the trajectory once it is
        known (``ahead`` seconds before the touch; None: from the start) — a bound, not a policy."""

        def truth(self, traj, ahead, path: bool = False):
            """``path``: the target is the true finger's own projection on the surface at the time the
            servo reaches it — the device under the finger all the way, its run-up exact."""
            self._obj = self.scene.object(traj.object_name)
            self.glide_m_s = 0.0  # the plan told the true touch point: sent there at once, as before the glide
            self._traj = traj if path else None
            self._touch = self._obj.project(traj.position(traj.t_surface))
            self._t_known = -1e9 if ahead is None else traj.t_surface - ahead
            self._now = self._t_sample = -1e9

        def update(self, t, p_robot_finger, p_robot_device=None):
            self._now = t + self.latency_s
            self._t_sample = t
            return super().update(t, p_robot_finger, p_robot_device)

        def _target(self, subj, p, c, h, in_contact, *approach):
            X = super()._target(subj, p, c, h, in_contact, *approach)
            if subj is self._obj and not in_contact and subj.mode.target != "centre" and self._now >= self._t_known:
                if self._traj is not None:
                    return self._obj.project(self._traj.position(min(self._servo_time(self._t_sample), self._traj.t_surface)))
                return self._touch.copy()
            return X

    return PerfectWorld


def _approach(case: tuple):
    """One approach (a Ray task under ``--workers``): a pure function of its case ``(scene name,
    trajectory, world, vision model, seed, in_place_m, stop_after_contact_s)``; ``world`` is
    ``{"predictor", "handover", "contact_model"}`` options of :class:`World`, or ``{"perfect": ahead,
    "contact_model"}`` for the perfect-prediction bound."""
    from vishap.world.closed_loop import run_approach
    from vishap.world.scene import load_scene
    from vishap.world.world import World

    name, tr, world, vision, seed, in_place_m, stop = case
    scene = load_scene(name)
    if "perfect" in world:
        w = _perfect_world_class()(scene, latency_s=vision.latency_s, contact_model=world["contact_model"])
        w.truth(tr, world["perfect"], path=world.get("path", False))
    else:
        w = World(scene, latency_s=vision.latency_s, **world)
    return run_approach(scene, tr, w, vision=vision, seed=seed, in_place_m=in_place_m, stop_after_contact_s=stop)


def run(args) -> dict:
    from vishap.scale import map_cases
    from vishap.scale.cli import engine_args
    from vishap.world.closed_loop import FingerPad, VisionModel
    from vishap.world.scene import load_scene
    from vishap.world.trajectories import make_approaches

    out = Path(args.out)
    vision = VisionModel(args.rate_hz, args.latency_ms / 1e3, args.noise_mm / 1e3, args.dropout)
    in_place_m = args.in_place_mm / 1e3
    scenes = {name: load_scene(name) for name in args.scenes.split(",") if name}
    t_start = time.perf_counter()
    cm = _system_contact_model()

    # every approach of every part below is one case, run at once (as Ray tasks with --workers)
    blocks: dict = {}
    for si, (name, scene) in enumerate(scenes.items()):
        trajs = make_approaches(scene, args.approaches, seed=args.seed + 100 * si, bow_fraction=args.bow)
        blocks[("scene", name)] = [(name, tr, {"contact_model": cm}, vision, args.seed + 1000 * si + i, in_place_m, None)
                                   for i, tr in enumerate(trajs)]
    pol_scene = scenes.get("wall") or load_scene("wall")
    trajs = make_approaches(pol_scene, args.policy_approaches, seed=args.seed + 7, bow_fraction=args.bow, slide=False)

    def on_policy_set(world, vm=vision):
        return [("wall", tr, world, vm, args.seed + 5000 + i, in_place_m, 0.02) for i, tr in enumerate(trajs)]

    for pred, ho, pcm in POLICIES:
        blocks[("policy", pred, ho, pcm)] = on_policy_set({"predictor": pred, "handover": ho, "contact_model": pcm})
    sens_models = {
        "camera_60hz_20ms": VisionModel(60.0, 0.020, vision.noise_m, vision.dropout),
        "no_noise_no_dropout": VisionModel(vision.rate_hz, vision.latency_s, 0.0, 0.0),
        "ideal_250hz_no_latency_no_noise": VisionModel(250.0, 0.0, 0.0, 0.0),
    }
    for label, vm in sens_models.items():
        blocks[("sens", label)] = on_policy_set({"contact_model": cm}, vm)
    for label, ahead in (("perfect_prediction", None), ("perfect_prediction_100ms_before_touch", 0.1)):
        blocks[("sens", label)] = on_policy_set({"perfect": ahead, "contact_model": cm})
    # the bound on readiness: the true finger's path as the target (the run-up exact) — what the servo allows
    blocks[("sens", "perfect_path")] = on_policy_set({"perfect": None, "path": True, "contact_model": cm})
    flat = [c for cases in blocks.values() for c in cases]
    done = iter(map_cases(_approach, flat, desc="world", **engine_args(args)))
    results = {key: [next(done) for _ in cases] for key, cases in blocks.items()}

    per_scene = {key[1]: rs for key, rs in results.items() if key[0] == "scene"}
    allres = [r for rs in per_scene.values() for r in rs]

    record = {"approaches": len(allres), **{k: v for k, v in _summary(allres, in_place_m).items() if k != "approaches"}}
    record["per_scene"] = {k: _summary(v, in_place_m) for k, v in per_scene.items()}

    # Fig. 6: wall — a straight line of force against fingertip depth
    charts = []
    fig6 = {}
    if "wall" in per_scene:
        d = np.concatenate([r.press_depth_m for r in per_scene["wall"]])
        f = np.concatenate([r.press_force_n for r in per_scene["wall"]])
        m = d > 0.0005
        slope, icpt, r2 = _line_fit(d[m], f[m])
        per = [_line_fit(r.press_depth_m[r.press_depth_m > 0.0005], r.press_force_n[r.press_depth_m > 0.0005])[2]
               for r in per_scene["wall"] if (r.press_depth_m > 0.0005).sum() > 20]
        k_pad = FingerPad().k_normal_n_m
        k_wall = scenes["wall"].objects[0].mode.law.stiffness_n_m
        record["wall_force_depth_r2"] = r2
        record["wall_force_depth_r2_min_per_approach"] = min(per) if per else None
        record["wall_slope_n_m"] = slope
        record["wall_slope_expected_n_m"] = k_pad * k_wall / (k_pad + k_wall)
        fig6["wall"] = (d, f, slope, icpt)
    if "button" in per_scene:
        clicks = [c for c in (_click(r.press_depth_m, r.press_force_n) for r in per_scene["button"])]
        ok = [c for c in clicks if c is not None and c[2] > 0.3 and c[0] > 2 * c[1] > 0]
        record["button_click_detected"] = bool(len(ok) >= 0.9 * len(clicks)) if clicks else False
        record["button_click_rate"] = len(ok) / len(clicks) if clicks else None
        good = [c for c in clicks if c is not None]
        if good:
            record["button_slopes_n_m"] = {
                "resist_median": float(np.median([c[0] for c in good])),
                "click_median": float(np.median([c[1] for c in good])),
                "drop_share_median": float(np.median([c[2] for c in good])),
            }
        d = np.concatenate([r.press_depth_m for r in per_scene["button"]])
        f = np.concatenate([r.press_force_n for r in per_scene["button"]])
        fig6["button"] = (d, f, None, None)
    if "fabric" in per_scene:
        ratios = [r.slide_friction_ratio for r in per_scene["fabric"] if r.slide_friction_ratio is not None]
        s = scenes["fabric"].objects[0].spec.surface
        record["fabric_friction_ratio_median"] = float(np.median(ratios)) if ratios else None
        record["fabric_mu_kinetic"] = s.mu_kinetic
    if "wall" in per_scene:
        ratios = [r.slide_friction_ratio for r in per_scene["wall"] if r.slide_friction_ratio is not None]
        record["wall_slide_friction_ratio_median"] = float(np.median(ratios)) if ratios else None
    if "panel" in per_scene:
        rs = per_scene["panel"]
        record["multi_object"] = {
            "scene": "panel",
            "approaches": len(rs),
            "subject_correct_at_contact_rate": float(np.mean([r.subject_at_contact == r.object_name for r in rs])),
            "subject_switches_median": float(np.median([max(len(r.subjects) - 1, 0) for r in rs])),
            "through_object_count": int(sum(r.through_object for r in rs)),
            # the passive face at its real size: a finger meeting it in transit can push it into an object
            "face_through_object_count": int(sum(r.face_through_object for r in rs)),
        }
    if fig6:
        charts.append(str(_plot_fig6(fig6, scenes, out / "fig6_force_depth.png")))

    # policies on the same approaches (wall scene, stop shortly after contact)
    policies = {}
    for pred, ho, pcm in POLICIES:
        rs = results[("policy", pred, ho, pcm)]
        tag = " (system)" if (pred, ho, pcm) == ("kalman", "hold", cm) else ""
        policies[f"{pred}+{ho}+{pcm}{tag}"] = {**_summary(rs, in_place_m), "errors_mm": [r.contact_error_m * 1e3 for r in rs],
                                                     "speeds": [r.speed_m_s for r in rs]}
    charts.append(str(_plot_policies(policies, out / "policies.png")))

    # what limits the meeting: the same approaches with better fingertip data (default policy), and
    # perfect prediction: the true touch point given to the world from the start, or only 100 ms
    # before the touch — what the servo alone allows
    sens = {key[1]: _brief(rs, trajs, in_place_m) for key, rs in results.items() if key[0] == "sens"}
    record["sensitivity"] = sens
    record["policies"] = {k: {kk: vv for kk, vv in v.items() if kk not in ("errors_mm", "speeds")} for k, v in policies.items()}

    record["servo_cost_us"] = _servo_cost(scenes)
    record["settings"] = {
        "vision": {"rate_hz": vision.rate_hz, "latency_s": vision.latency_s, "noise_m": vision.noise_m, "dropout": vision.dropout},
        "in_place_mm": args.in_place_mm, "speeds_m_s": [0.1, 0.2, 0.3, 0.4, 0.5], "bow_fraction": args.bow,
        "predictor": "kalman", "handover": "hold", "contact_model": cm, "seed": args.seed,
        "servo": _servo_settings(),
    }
    record["charts"] = charts
    record["wall_time_s"] = time.perf_counter() - t_start
    record["machine"] = machine_info()
    return record


def _plot_fig6(fig6, scenes, path):
    fig, axes = new_figure(1, len(fig6), figsize=(5.2 * len(fig6), 4.0), squeeze=False)
    for ax, (name, (d, f, slope, icpt)) in zip(axes[0], fig6.items()):
        x = -d * 1e3  # distance of the fingertip to the surface (negative: under it), as in Fig. 6
        ax.plot(x, f, ".", ms=1.5, alpha=0.25, color="tab:blue", label="servo ticks")
        bins = np.arange(np.floor(x.min() * 4) / 4, x.max() + 0.25, 0.25)
        idx = np.digitize(x, bins)
        cx = [x[idx == i].mean() for i in np.unique(idx) if (idx == i).sum() > 5]
        cy = [f[idx == i].mean() for i in np.unique(idx) if (idx == i).sum() > 5]
        ax.plot(cx, cy, "-", color="k", lw=2, label="average force")
        if slope is not None:
            xs = np.linspace(min(cx), -0.5, 10)
            ax.plot(xs, slope * (-xs / 1e3) + icpt, "--", color="tab:red", label=f"line fit, {slope:.0f} N/m")
        if name == "button":
            o = scenes["button"].objects[0].spec
            ax.axvline(-o.trigger_depth_m * 1e3, color="tab:orange", ls=":", label="trigger depth (key)")
            ax.axvline(-o.travel_m * 1e3, color="tab:gray", ls=":", label="bottom (key)")
        ax.set_xlabel("fingertip distance to the surface (mm, negative: under it)")
        ax.set_ylabel("device force along the normal (N)")
        ax.set_title(f"{name}: force against fingertip distance (VisHap Fig. 6)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, path)


def _plot_policies(policies, path):
    fig, (a1, a2) = new_figure(1, 2, figsize=(13, 4.6))
    names = list(policies)
    a1.boxplot([np.maximum(policies[k]["errors_mm"], 1e-3) for k in names], showfliers=True)
    a1.set_xticks(range(1, len(names) + 1), names, rotation=30, fontsize=6, ha="right")
    a1.set_yscale("log")
    a1.axhline(1.0, color="tab:red", ls="--", lw=1, label="goal 1 mm")
    a1.set_ylabel("contact-position error (mm)")
    a1.set_title("same approaches, each policy")
    a1.legend(fontsize=8)
    for k in names:
        sp = np.array(policies[k]["speeds"])
        e = np.array(policies[k]["errors_mm"])
        us = np.unique(sp)
        mark = "system" in k
        a2.plot(us, [np.mean(e[sp == u] <= 1.0) for u in us], "o-", lw=2.5 if mark else 1.0,
                alpha=1.0 if mark else 0.55, label=f"{k}: {np.mean(e <= 1.0):.0%}")
    a2.set_xlabel("peak finger speed (m/s)")
    a2.set_ylabel("device in place (≤ 1 mm) at the touch")
    a2.set_ylim(-0.05, 1.05)
    a2.grid(alpha=0.3)
    a2.legend(fontsize=6.5, loc="center left", bbox_to_anchor=(1.01, 0.5))
    return save_figure(fig, path)
