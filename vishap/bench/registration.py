"""``vishap bench registration``: absolute orientation against its peers, and the camera-robot procedure.

Implements the measurements behind VisHap §2.2 (Eq. 3). On the same synthetic point pairs (a cloud
the size of the reachable box, destination noise σ per axis, a share of gross outliers):

* accuracy against σ, with the Cramér–Rao floor: for N pairs with isotropic noise σ on one side,
  an efficient estimator maps the N points with RMS error ``σ·√(6/N)`` (6 pose parameters);
* accuracy against the outlier fraction (robust estimators);
* speed against N;
* the camera-to-robot procedure on rendered images: error against the number of poses.

Methods: ours (closed form, LMedS, RANSAC), Open3D's ``TransformationEstimationPointToPoint`` and
``registration_ransac_based_on_correspondence``, OpenCV's ``estimateAffine3D`` (RANSAC affine) and
its Umeyama overload (``force_rotation=True``), SciPy's ``Rotation.align_vectors`` (Kabsch).
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, median_us, new_figure, save_figure, time_calls
from vishap.registration.rigid import RigidTransform

HELP = "absolute orientation vs Open3D / OpenCV / SciPy (noise, outliers, speed); camera-robot error vs poses"

#: the setting ``vishap bench all`` uses (about a minute here)
QUICK_ARGS = ["--trials", "30", "--poses", "4,8,12", "--pose-seeds", "1"]

_EXTENT = np.array([0.20, 0.13, 0.16])  # the reachable box, metres


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--trials", type=int, default=200, help="random trials per setting (default 200)")
    p.add_argument("--points", type=int, default=20, help="point pairs per trial (default 20)")
    p.add_argument("--poses", default="4,6,8,12,16,24", help="pose counts for the camera-robot curve")
    p.add_argument("--pose-seeds", type=int, default=2, help="seeds per pose count (default 2)")
    p.add_argument("--no-render", action="store_true", help="skip the rendered camera-robot part")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--stereo-dir", default=".pytest_cache/d/opencv-doc-stereo",
                   help="folder with OpenCV's left*.jpg/right*.jpg sample pairs (skipped when absent)")


# ---------------------------------------------------------------------------------------- methods
def _ours(src, dst):
    return RigidTransform.from_estimate(src, dst).T


def _ours_lmeds(src, dst):
    return RigidTransform.from_estimate_robust(src, dst, seed=0).T


def _ours_ransac(src, dst, thr):
    return RigidTransform.from_estimate_robust(src, dst, threshold=thr, seed=0).T


def _o3d_p2p(src, dst):
    import open3d as o3d

    a = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(src))
    b = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(dst))
    corr = o3d.utility.Vector2iVector(np.repeat(np.arange(len(src), dtype=np.int32)[:, None], 2, axis=1))
    return o3d.pipelines.registration.TransformationEstimationPointToPoint().compute_transformation(a, b, corr)


def _o3d_ransac(src, dst, thr, refit=False):
    import open3d as o3d

    reg = o3d.pipelines.registration
    a = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(src))
    b = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(dst))
    corr = o3d.utility.Vector2iVector(np.repeat(np.arange(len(src), dtype=np.int32)[:, None], 2, axis=1))
    o3d.utility.random.seed(0)
    res = reg.registration_ransac_based_on_correspondence(
        a, b, corr, thr, reg.TransformationEstimationPointToPoint(False), 3, [],
        reg.RANSACConvergenceCriteria(2000, 0.999))
    if refit and len(res.correspondence_set) >= 3:  # least squares on its inliers, as its ICP stage would
        return reg.TransformationEstimationPointToPoint().compute_transformation(a, b, res.correspondence_set)
    return np.asarray(res.transformation)


def _cv2_affine_ransac(src, dst, thr):
    import cv2

    ok, A, _ = cv2.estimateAffine3D(src, dst, ransacThreshold=thr, confidence=0.999)
    T = np.eye(4)
    if ok and A is not None:
        T[:3] = A
    else:
        T[:3] = np.nan
    return T


def _cv2_umeyama(src, dst):
    import cv2

    A, scale = cv2.estimateAffine3D(src, dst, force_rotation=True)
    T = np.eye(4)
    T[:3] = A
    return T


def _scipy_kabsch(src, dst):
    from scipy.spatial.transform import Rotation

    ms, md = src.mean(axis=0), dst.mean(axis=0)
    rot, _ = Rotation.align_vectors(dst - md, src - ms)
    T = np.eye(4)
    T[:3, :3] = rot.as_matrix()
    T[:3, 3] = md - T[:3, :3] @ ms
    return T


PLAIN = {"ours (closed form)": _ours, "Open3D point-to-point": _o3d_p2p, "OpenCV Umeyama (force_rotation)": _cv2_umeyama,
         "SciPy align_vectors": _scipy_kabsch, "ours (LMedS)": _ours_lmeds,
         "OpenCV estimateAffine3D (RANSAC, affine)": lambda s, d: _cv2_affine_ransac(s, d, 2e-3)}


def _robust(thr):
    return {"ours (closed form)": _ours, "ours (LMedS)": _ours_lmeds,
            "ours (RANSAC)": lambda s, d: _ours_ransac(s, d, thr),
            "Open3D RANSAC": lambda s, d: _o3d_ransac(s, d, thr),
            "Open3D RANSAC + point-to-point refit": lambda s, d: _o3d_ransac(s, d, thr, refit=True),
            "OpenCV estimateAffine3D (RANSAC, affine)": lambda s, d: _cv2_affine_ransac(s, d, thr)}


# ---------------------------------------------------------------------------------------- data
def _random_rigid(rng) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=int(rng.integers(1 << 31))).as_matrix()
    T[:3, 3] = rng.uniform(-0.5, 0.5, 3)
    return T


def _pairs(rng, n, sigma, outlier_frac=0.0):
    T = _random_rigid(rng)
    src = (rng.random((n, 3)) - 0.5) * _EXTENT
    clean = src @ T[:3, :3].T + T[:3, 3]
    dst = clean + rng.normal(scale=sigma, size=(n, 3))
    out = np.zeros(n, bool)
    k = int(round(outlier_frac * n))
    if k:
        idx = rng.choice(n, k, replace=False)
        out[idx] = True
        d = rng.normal(size=(k, 3))
        dst[idx] += d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.005, 0.05, (k, 1))
    return src, dst, clean, T, out


def _map_rms(T_est, src, clean) -> float:
    """RMS distance between the estimate and the truth over the (inlier) source points, metres."""
    if not np.all(np.isfinite(T_est)):
        return math.inf
    return float(np.sqrt(np.mean(np.sum((src @ T_est[:3, :3].T + T_est[:3, 3] - clean) ** 2, axis=1))))


# ---------------------------------------------------------------------------------------- parts
def _noise_sweep(rng, trials, n):
    sigmas_mm = [0.1, 0.25, 0.5, 1.0, 2.0]
    res = {name: [] for name in PLAIN}
    for s_mm in sigmas_mm:
        errs = {name: [] for name in PLAIN}
        for _ in range(trials):
            src, dst, clean, _, _ = _pairs(rng, n, s_mm * 1e-3)
            for name, f in PLAIN.items():
                try:
                    errs[name].append(_map_rms(f(src, dst), src, clean))
                except Exception:  # a peer that fails counts as infinite error
                    errs[name].append(math.inf)
        for name in PLAIN:
            e = np.asarray(errs[name])
            res[name].append(float(np.sqrt(np.mean(e**2))) * 1e3)  # RMS over trials, mm
    floor = [s * math.sqrt(6.0 / n) for s in sigmas_mm]
    ratio = {name: [e / f for e, f in zip(v, floor)] for name, v in res.items()}
    return {"sigma_mm": sigmas_mm, "points": n, "map_rms_mm": res, "floor_mm": floor, "ratio_to_floor": ratio}


def _outlier_sweep(rng, trials, n, sigma_mm=0.5):
    fracs = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    thr = 4.0 * sigma_mm * 1e-3  # ≈ the 99.9 % gate of a 3-D Gaussian
    methods = _robust(thr)
    res = {name: {"map_rms_mm": [], "correct_fraction": [], "ratio_to_floor": [], "median_us": []} for name in methods}
    floors = []
    for frac in fracs:
        n_in = n - int(round(frac * n))
        floor = sigma_mm * math.sqrt(6.0 / n_in)
        floors.append(floor)
        errs = {name: [] for name in methods}
        times = {name: [] for name in methods}
        for _ in range(trials):
            src, dst, clean, _, out = _pairs(rng, n, sigma_mm * 1e-3, frac)
            for name, f in methods.items():
                t0 = time.perf_counter()
                try:
                    T = f(src, dst)
                except Exception:
                    T = np.full((4, 4), np.nan)
                times[name].append(time.perf_counter() - t0)
                errs[name].append(_map_rms(T, src[~out], clean[~out]) * 1e3)
        for name in methods:
            e = np.asarray(errs[name])
            fin = e[np.isfinite(e)]
            res[name]["map_rms_mm"].append(float(np.median(e)) if len(e) else None)
            # "correct": within 3× the floor (a gross failure is far beyond it)
            res[name]["correct_fraction"].append(float(np.mean(e < 3 * floor)))
            res[name]["ratio_to_floor"].append(float(np.sqrt(np.mean(fin**2))) / floor if len(fin) else None)
            res[name]["median_us"].append(median_us(np.asarray(times[name])))
    return {"outlier_fraction": fracs, "sigma_mm": sigma_mm, "points": n, "threshold_mm": thr * 1e3,
            "floor_mm": floors, "methods": res}


def _points_sweep(rng, trials, sigma_mm=0.5):
    """Error against the number of pairs N at fixed σ (the floor falls as 1/√N)."""
    sizes = [3, 4, 6, 10, 20, 50, 200]
    methods = {k: PLAIN[k] for k in ("ours (closed form)", "Open3D point-to-point", "OpenCV Umeyama (force_rotation)")}
    res = {name: [] for name in methods}
    for n in sizes:
        errs = {name: [] for name in methods}
        for _ in range(trials):
            src, dst, clean, _, _ = _pairs(rng, n, sigma_mm * 1e-3)
            for name, f in methods.items():
                errs[name].append(_map_rms(f(src, dst), src, clean))
        for name in methods:
            res[name].append(float(np.sqrt(np.mean(np.square(errs[name])))) * 1e3)
    return {"points": sizes, "sigma_mm": sigma_mm, "map_rms_mm": res,
            "floor_mm": [sigma_mm * math.sqrt(min(6.0, 3.0 * n - 3.0) / n) for n in sizes]}


def _speed(rng):
    sizes = [10, 100, 1000, 10000]
    out = {name: [] for name in list(PLAIN) + ["ours (RANSAC)", "Open3D RANSAC"]}
    fns = {**PLAIN, "ours (RANSAC)": lambda s, d: _ours_ransac(s, d, 2e-3),
           "Open3D RANSAC": lambda s, d: _o3d_ransac(s, d, 2e-3)}
    for n in sizes:
        src, dst, _, _, _ = _pairs(rng, n, 0.5e-3, 0.2)
        for name, f in fns.items():
            reps = 30 if n <= 1000 else 5
            out[name].append(median_us(time_calls(lambda: f(src, dst), reps, warmup=2)))
    return {"points": sizes, "median_us": out}


def _camera_robot(pose_counts, seeds, out: Path):
    try:
        from vishap.registration.sim import SimCalibration
    except ImportError as exc:
        return {"skipped": f"the synthetic renderer is not available ({exc})"}
    rows = []
    sim = SimCalibration(seed=0)
    for n in pose_counts:
        for s in range(seeds):
            t0 = time.perf_counter()
            rep = sim.run(n_poses=n, seed=s)
            rep["wall_s"] = time.perf_counter() - t0
            for variant in ("closed_form", "reprojection_refined"):
                r = rep[variant]
                rows.append({"poses": n, "seed": s, "variant": variant, "poses_used": r["poses_used"],
                             "poses_visited": rep["poses_visited"],
                             "per_axis_error_mm": r["per_axis_error_mm"], "rms_mm": r["rms_mm"],
                             "rotation_error_deg": r["rotation_error_deg"],
                             "translation_error_mm": r["translation_error_mm"],
                             "workspace_per_axis_error_mm": r["workspace_per_axis_error_mm"],
                             "workspace_max_error_mm": r["workspace_max_error_mm"], "wall_s": rep["wall_s"]})
    # the pose set matters: the same number of poses, spread (ours), uniform random, clustered
    designs = []
    n_d = 8 if 8 in pose_counts else pose_counts[len(pose_counts) // 2]
    for design in ("maximin", "random", "cluster"):
        for s in range(seeds):
            rep = sim.run(n_poses=n_d, seed=s, design=design)
            for variant in ("closed_form", "reprojection_refined"):
                r = rep[variant]
                designs.append({"design": design, "poses": n_d, "seed": s, "variant": variant,
                                "workspace_per_axis_error_mm": r["workspace_per_axis_error_mm"],
                                "workspace_max_error_mm": r["workspace_max_error_mm"],
                                "rotation_error_deg": r["rotation_error_deg"]})
    _chart_designs(designs, out / "registration_pose_designs.png")
    pose_set = sim.run(n_poses=max(pose_counts), seed=0, keep_observations=True)["observations"]
    _chart_poses(pose_set, out / "registration_pose_set.png")
    _chart_camera_robot(rows, out / "registration_camera_robot.png")
    return {"rows": rows, "designs": designs, "pose_set": pose_set, "render_size": list(sim.size)}


def _stereo(folder: Path):
    """Our stereo calibration against OpenCV's stereo_calib procedure on OpenCV's sample pairs."""
    from vishap.registration.stereo_calib import Board, calibrate_stereo, opencv_sample_stereo_calib

    left, right = sorted(folder.glob("left*.jpg")), sorted(folder.glob("right*.jpg"))
    if not left or len(left) != len(right):
        return {"skipped": f"no sample pairs in {folder} (run the registration tests once to fetch them)"}
    board = Board(9, 6, 0.025)
    out = {"pairs": len(left)}
    for name, fn in (("ours_k5", lambda: calibrate_stereo(left, right, board).summary()),
                     ("ours_rational", lambda: calibrate_stereo(left, right, board, model="rational").summary()),
                     ("opencv_stereo_calib_sample", lambda: opencv_sample_stereo_calib(left, right, board))):
        t0 = time.perf_counter()
        r = fn()
        out[name] = {"rms_px": r["rms_px"], "pairs_used": r["pairs_used"], "baseline_squares": r["baseline_m"] / 0.025,
                     "fx_px": r["fx_px"], "wall_s": time.perf_counter() - t0}
    return out


# ---------------------------------------------------------------------------------------- charts
def _chart_noise(r, path):
    fig, ax = new_figure(figsize=(6.4, 4.2))
    for name, v in r["map_rms_mm"].items():
        ax.plot(r["sigma_mm"], v, marker="o", label=name, alpha=0.8)
    ax.plot(r["sigma_mm"], r["floor_mm"], "k--", label="Cramér–Rao floor σ√(6/N)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("noise σ per axis (mm)")
    ax.set_ylabel("mapping RMS error (mm)")
    ax.set_title(f"absolute orientation, N = {r['points']} pairs")
    ax.legend(fontsize=7)
    save_figure(fig, path)


def _chart_outliers(r, path):
    fig, axes = new_figure(1, 2, figsize=(10, 4))
    for name, v in r["methods"].items():
        axes[0].plot(r["outlier_fraction"], v["map_rms_mm"], marker="o", label=name)
        axes[1].plot(r["outlier_fraction"], v["correct_fraction"], marker="o", label=name)
    axes[0].plot(r["outlier_fraction"], r["floor_mm"], "k--", label="floor (inliers)")
    axes[0].set_yscale("log")
    axes[0].set_xlabel("outlier fraction")
    axes[0].set_ylabel("median mapping RMS error (mm)")
    axes[1].set_xlabel("outlier fraction")
    axes[1].set_ylabel("trials within 3× floor")
    axes[0].set_title(f"σ = {r['sigma_mm']} mm, N = {r['points']}")
    axes[1].legend(fontsize=7)
    save_figure(fig, path)


def _chart_points(r, path):
    fig, ax = new_figure(figsize=(6.4, 4.2))
    for name, v in r["map_rms_mm"].items():
        ax.plot(r["points"], v, marker="o", label=name, alpha=0.8)
    ax.plot(r["points"], r["floor_mm"], "k--", label="floor")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("point pairs N")
    ax.set_ylabel("mapping RMS error (mm)")
    ax.set_title(f"σ = {r['sigma_mm']} mm")
    ax.legend(fontsize=7)
    save_figure(fig, path)


def _chart_tradeoff(r, path):
    """Speed (x) against accuracy (y), clean and with 30 % outliers (N = 40, σ = 0.5 mm)."""
    fig, ax = new_figure(figsize=(10.5, 4.6))
    fr = r["outlier_fraction"]
    for name, v in r["methods"].items():
        for k, (frac, mk) in enumerate(((0.0, "o"), (0.3, "^"))):
            i = fr.index(frac)
            ax.scatter(v["median_us"][i], v["map_rms_mm"][i], marker=mk, s=40,
                       label=f"{name} ({int(frac * 100)} % outliers)", color=f"C{list(r['methods']).index(name)}")
    for frac, ls in ((0.0, ":"), (0.3, "--")):
        ax.axhline(r["floor_mm"][fr.index(frac)], color="k", ls=ls, lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("median time per estimate (µs)")
    ax.set_ylabel("median mapping RMS error (mm)")
    ax.set_title(f"speed vs accuracy, N = {r['points']}, σ = {r['sigma_mm']} mm (lines: floors)")
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    save_figure(fig, path)


def _chart_speed(r, path):
    fig, ax = new_figure(figsize=(6.4, 4.2))
    for name, v in r["median_us"].items():
        ax.plot(r["points"], v, marker="o", label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("point pairs N")
    ax.set_ylabel("median time per estimate (µs)")
    ax.legend(fontsize=7)
    save_figure(fig, path)


def _chart_camera_robot(rows, path):
    fig, axes = new_figure(1, 2, figsize=(10, 4))
    for variant, style in (("closed_form", "o-"), ("reprojection_refined", "s--")):
        ns = sorted({r["poses"] for r in rows})
        pa = [np.mean([np.max(r["per_axis_error_mm"]) for r in rows if r["poses"] == n and r["variant"] == variant])
              for n in ns]
        ws = [np.mean([np.max(r["workspace_per_axis_error_mm"]) for r in rows if r["poses"] == n and r["variant"] == variant])
              for n in ns]
        axes[0].plot(ns, pa, style, label=f"{variant}: fitted pairs (VisHap's figure)")
        axes[0].plot(ns, ws, style, alpha=0.5, label=f"{variant}: workspace grid vs truth")
        rot = [np.mean([r["rotation_error_deg"] for r in rows if r["poses"] == n and r["variant"] == variant]) for n in ns]
        axes[1].plot(ns, rot, style, label=variant)
    axes[0].axhline(0.5, color="k", ls=":", label="VisHap: 0.5 mm per axis")
    axes[0].set_xlabel("poses")
    axes[0].set_ylabel("worst axis, mean |error| (mm)")
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel("poses")
    axes[1].set_ylabel("rotation error (deg)")
    axes[1].legend(fontsize=7)
    save_figure(fig, path)


def _chart_designs(rows, path):
    fig, ax = new_figure(figsize=(6.4, 4.2))
    names = ["maximin", "random", "cluster"]
    for k, variant in enumerate(("closed_form", "reprojection_refined")):
        vals = [np.mean([r["workspace_max_error_mm"] for r in rows if r["design"] == d and r["variant"] == variant])
                for d in names]
        ax.bar(np.arange(3) + 0.38 * k, vals, width=0.36, label=variant)
    ax.set_xticks(np.arange(3) + 0.19, [f"{d}\n({rows[0]['poses']} poses)" for d in names])
    ax.set_yscale("log")
    ax.set_ylabel("max error over the workspace grid (mm)")
    ax.set_title("the pose set matters")
    ax.legend(fontsize=7)
    save_figure(fig, path)


def _chart_poses(obs, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = np.asarray(obs["p_robot"], dtype=float)
    ok = np.asarray(obs["ok"], dtype=bool)
    fig = plt.figure(figsize=(5.5, 4.5))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(*p[ok].T, c="tab:green", label="used")
    if (~ok).any():
        ax.scatter(*p[~ok].T, c="tab:red", marker="x", label="dropped")
    for i, q in enumerate(p):
        ax.text(*q, str(i), fontsize=6)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title("camera-robot pose set (robot frame)")
    ax.legend(fontsize=7)
    save_figure(fig, path)


# ---------------------------------------------------------------------------------------- run
def run(args: argparse.Namespace) -> dict:
    from vishap._core.results import progress

    out = Path(args.out)
    rng = np.random.default_rng(args.seed)
    # one bar over the benchmark's parts (each a sweep of its own; the camera-robot part renders)
    bar = progress(total=5 + (not args.no_render), desc="bench registration", unit="part",
                   quiet=getattr(args, "quiet", False))

    def part(name, fn, *a):
        bar.set_postfix_str(name)
        r = fn(*a)
        bar.update(1)
        return r

    noise = part("noise", _noise_sweep, rng, args.trials, args.points)
    outliers = part("outliers", _outlier_sweep, rng, args.trials, max(args.points, 40))
    points = part("points", _points_sweep, rng, args.trials)
    speed = part("speed", _speed, rng)
    _chart_noise(noise, out / "registration_noise.png")
    _chart_points(points, out / "registration_points.png")
    _chart_tradeoff(outliers, out / "registration_tradeoff.png")
    _chart_outliers(outliers, out / "registration_outliers.png")
    _chart_speed(speed, out / "registration_speed.png")
    rec = {"machine": machine_info(), "noise": noise, "points": points, "outliers": outliers, "speed": speed}
    i = noise["sigma_mm"].index(0.5)
    rec["goal_noise_floor_at_0p5mm"] = {name: v[i] for name, v in noise["ratio_to_floor"].items()}
    rec["goal_correct_at_30pct_outliers"] = {name: v["correct_fraction"][outliers["outlier_fraction"].index(0.3)]
                                             for name, v in outliers["methods"].items()}
    rec["stereo_calibration"] = part("stereo calibration", _stereo, Path(args.stereo_dir))
    if not args.no_render:
        rec["camera_robot"] = part("camera-robot", _camera_robot, [int(s) for s in args.poses.split(",")],
                                   args.pose_seeds, out)
    bar.close()
    rec["charts"] = sorted(str(p) for p in out.glob("registration_*.png"))
    return rec
