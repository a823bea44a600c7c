"""``vishap bench robot``: cost of one 1 kHz servo cycle against a bare MuJoCo step and a plain PD step.

Three loops on the same MuJoCo arm, measured in interleaved rounds so that load on the machine
hits all of them alike:

* ``bare_mujoco_step`` — ``mj_step`` alone (the floor);
* ``numpy_pd_step`` — the peer a user would write first: read ``qpos``, ``mj_jacSite`` for the
  Jacobian, ``qfrc_bias`` for gravity, a NumPy PD law, write ``ctrl``, ``mj_step``;
* ``servo_cycle`` — :meth:`vishap.robot.servo.ServoLoop.tick` (read → target shaping → filtered PD
  → gravity compensation → limits → write → ``mj_step``), tracking a target sampled at 30 Hz.

Writes ``robot.png`` (per-cycle time distributions) and returns the medians, the 99th percentiles
and ``realtime_factor`` = 1 ms ÷ servo-cycle median.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "servo-cycle cost vs bare MuJoCo step and a plain NumPy PD step (µs, real-time factor)"


def add_arguments(parser) -> None:
    parser.add_argument("--ticks", type=int, default=20000, help="timed cycles per loop (default 20000)")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    parser.add_argument("--policy", default="hold", help="X_d gap policy of the servo loop")


def _target(t: float) -> np.ndarray:
    """A slow Lissajous target inside the reachable box, sampled at 30 Hz."""
    ts = np.floor(t * 30.0) / 30.0
    return np.array([0.2 + 0.05 * np.sin(1.3 * ts), 0.04 * np.sin(0.9 * ts), -0.12 + 0.04 * np.cos(1.1 * ts)])


def _servo_loop(n: int, policy: str):
    from vishap.robot import Controller, Gains, MujocoPlant, ServoLoop
    from vishap.world.scene import demo_passive_object

    plant = MujocoPlant(passive_object=demo_passive_object())
    servo = ServoLoop(plant, Controller(plant.params, Gains(), limits=plant.limits), policy=policy)
    targets = [_target(i * 1e-3) for i in range(n)]
    # precomputed X_d objects: a new array only when the 30 Hz sample changes, as vision delivers
    for i in range(1, n):
        if np.array_equal(targets[i], targets[i - 1]):
            targets[i] = targets[i - 1]

    def run(durations: np.ndarray, k0: int) -> None:
        pc = time.perf_counter
        tick = servo.tick
        for i in range(len(durations)):
            k = k0 + i
            X = targets[k % n]
            t0 = pc()
            tick(k * 1e-3, X)
            durations[i] = pc() - t0

    return run, plant, servo


def _bare_loop():
    import mujoco

    from vishap.robot import MujocoPlant
    from vishap.world.scene import demo_passive_object

    plant = MujocoPlant(passive_object=demo_passive_object())
    m, d = plant.model, plant.data
    d.ctrl[:] = (0.0, 0.02, 0.05)

    def run(durations: np.ndarray, k0: int) -> None:
        pc = time.perf_counter
        step = mujoco.mj_step
        for i in range(len(durations)):
            t0 = pc()
            step(m, d)
            durations[i] = pc() - t0
        mujoco.mj_resetData(m, d)

    return run


def _numpy_pd_loop(n: int):
    """PD + gravity compensation the direct way: mj_jacSite, qfrc_bias, NumPy."""
    import mujoco

    from vishap.robot import MujocoPlant
    from vishap.world.scene import demo_passive_object

    plant = MujocoPlant(passive_object=demo_passive_object())
    m, d = plant.model, plant.data
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "tip")
    jacp = np.zeros((3, m.nv))
    # actuator moment arms: ctrl → qfrc is Eᵀ; gravity in motor torques is E⁻ᵀ qfrc_bias
    E_inv_T = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]])
    from vishap.robot import Gains

    kp, kv = Gains().kp, Gains().kv
    targets = [_target(i * 1e-3) for i in range(n)]

    def run(durations: np.ndarray, k0: int) -> None:
        pc = time.perf_counter
        for i in range(len(durations)):
            X = targets[(k0 + i) % n]
            t0 = pc()
            mujoco.mj_jacSite(m, d, jacp, None, site)
            p = d.site_xpos[site]
            v = jacp @ d.qvel
            F = kp * (X - p) - kv * v
            tau_mj = jacp.T @ F + d.qfrc_bias
            d.ctrl[:] = np.clip(E_inv_T @ tau_mj, -3.0, 3.0)
            mujoco.mj_step(m, d)
            durations[i] = pc() - t0

    return run


def run(args) -> dict:
    n, rounds = int(args.ticks), int(args.rounds)
    per = max(1, n // rounds)
    servo_run, plant, servo = _servo_loop(n, args.policy)
    bare_run = _bare_loop()
    pd_run = _numpy_pd_loop(n)
    res = {"servo_cycle": [], "bare_mujoco_step": [], "numpy_pd_step": []}
    from vishap._core.results import progress

    for r in progress(range(rounds), desc="bench robot", unit="round", quiet=getattr(args, "quiet", False)):
        for name, fn in (("bare_mujoco_step", bare_run), ("numpy_pd_step", pd_run), ("servo_cycle", servo_run)):
            d = np.empty(per)
            fn(d[: min(300, per)], r * per)  # warm-up, discarded
            fn(d, r * per)
            res[name].append(d)
    us = {k: np.concatenate(v) * 1e6 for k, v in res.items()}
    # tracking sanity of the timed servo run: where it ended vs its last target
    err_mm = float(np.linalg.norm(plant.read().p_robot - np.array(servo.controller.target)) * 1e3)

    fig, ax = new_figure(figsize=(7, 4))
    names = ["bare_mujoco_step", "numpy_pd_step", "servo_cycle"]
    ax.boxplot([us[k] for k in names], showfliers=False)
    ax.set_xticks([1, 2, 3], ["bare mj_step", "NumPy PD + mj_step", "vishap servo tick"])
    ax.axhline(25.0, color="r", ls="--", lw=1, label="goal 25 µs")
    for i, k in enumerate(names, start=1):
        ax.annotate(f"{np.median(us[k]):.1f} µs", (i, np.median(us[k])), xytext=(8, 0), textcoords="offset points")
    ax.set_ylabel("time per 1 kHz cycle (µs)")
    ax.set_title(f"Servo cycle cost, {n} cycles each, {rounds} interleaved rounds")
    ax.legend()
    out = Path(args.out)
    save_figure(fig, out / "robot.png")

    servo_med = float(np.median(us["servo_cycle"]))
    bare_med = float(np.median(us["bare_mujoco_step"]))
    pd_med = float(np.median(us["numpy_pd_step"]))
    return {
        "bench": "robot",
        "servo_cycle_us_median": servo_med,
        "bare_mujoco_step_us_median": bare_med,
        "numpy_pd_step_us_median": pd_med,
        "servo_cycle_us_p99": float(np.percentile(us["servo_cycle"], 99)),
        "bare_mujoco_step_us_p99": float(np.percentile(us["bare_mujoco_step"], 99)),
        "numpy_pd_step_us_p99": float(np.percentile(us["numpy_pd_step"], 99)),
        "realtime_factor": 1000.0 / servo_med,
        "servo_over_bare_ratio": servo_med / bare_med,
        "servo_over_numpy_pd_ratio": servo_med / pd_med,
        "goal_us": 25.0,
        "meets_goal": servo_med <= 25.0,
        "ticks": n,
        "rounds": rounds,
        "policy": args.policy,
        "final_tracking_error_mm": err_mm,
        "chart": str(out / "robot.png"),
        "machine": machine_info(),
    }
