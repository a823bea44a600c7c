"""``vishap bench scale``: speed-up of building synthetic sequences against workers, a simulated
multi-node cluster, and what one more machine would buy (issue 18, item 5).

The same jobs (``--seqs`` sequences of ``--frames`` frames, wall script, seeds 0…) are built in
this process (``workers=1``, what ``vishap synth`` in a loop does) and on a local Ray instance with
``--workers`` workers, back to back in each of ``--rounds`` rounds (the order alternates per
round, so a change in the machine's load hits both). Ray's start-up is timed apart from the
builds; one untimed build in each mode first pays the imports and the workers' start. Then the
jobs are built on a cluster simulated on this machine (``ray.cluster_utils.Cluster``: a head and
``--nodes``−1 more nodes, one CPU each) through its address, as ``--address`` does. Every build's
sequences are compared byte for byte with the serial build's.

One more machine: from the measured throughput of this machine (sequences per second at
``--workers``) and the bytes per sequence, the projected time of a ``--project`` sequence data set
on 1 and 2 machines, and how many machines a 1 Gbit/s link into the driver carries before the
sequences' bytes (which travel through Ray's object store to the driver) saturate it.

Storage (issue 18, item 4): ``--store-frames`` rendered frames of the wall script (camera effects
on) at each ``--store-resolutions`` are written as PNGs and as FFV1 videos
(:mod:`vishap.scale.store`), ``--store-rounds`` times with the order alternating, and read back:
bytes, write and read time per frame (wall; write also CPU, ffmpeg's processes included), and
whether every pixel read back equals what was written. Every timing carries the machine's 1-minute
load average before and after it (the machine is shared).
"""
from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "speed-up of sequence building against Ray workers, a simulated multi-node cluster, one more machine"
QUICK_ARGS = ["--seqs", "2", "--frames", "2", "--resolution", "160x120", "--rounds", "1", "--nodes", "2",
              "--store-frames", "2", "--store-resolutions", "160x120", "--store-rounds", "1"]
_LINK_BYTES_S = 125e6  # 1 Gbit/s

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run"]


def add_arguments(parser) -> None:
    parser.add_argument("--seqs", type=int, default=6, help="sequences per build (seeds 0 … seqs-1)")
    parser.add_argument("--frames", type=int, default=20, help="frames per sequence")
    parser.add_argument("--resolution", default="320x240", help="image size (WxH)")
    parser.add_argument("--workers", type=int, default=2, help="local Ray workers compared with one")
    parser.add_argument("--rounds", type=int, default=3, help="serial/parallel pairs, order alternating")
    parser.add_argument("--nodes", type=int, default=2, help="nodes of the simulated cluster (0: skip it)")
    parser.add_argument("--project", type=int, default=1000, help="data-set size (sequences) for the projection")
    parser.add_argument("--store-frames", type=int, default=20, help="frames written per store and round")
    parser.add_argument("--store-resolutions", default="320x240,640x480", help="image sizes of the storage test")
    parser.add_argument("--store-rounds", type=int, default=3, help="PNG/video pairs, order alternating")


def _jobs(args):
    from vishap.scale import Job, spec_parameters
    from vishap.sim.sequence import SequenceSpec

    w, h = (int(v) for v in args.resolution.lower().split("x"))
    jobs = []
    for s in range(args.seqs):
        spec = SequenceSpec(scene="wall", frames=args.frames, seed=s, width=w, height=h, start_s=1.0)
        jobs.append(Job(f"seed-{s:06d}", spec, spec_parameters(spec)))
    return jobs


def _digests(folder: Path) -> dict:
    from vishap.scale.manifest import file_hashes

    return {p.name: file_hashes(p) for p in sorted(folder.iterdir()) if p.name.startswith("seed-")}


def _build(jobs, out: Path, **kw) -> dict:
    from vishap.scale import build_sequences
    from vishap.scale.manifest import load_manifest

    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    summary = build_sequences(jobs, out, progress=False, **kw)
    wall = time.perf_counter() - t0
    entries = load_manifest(out)["sequences"].values()
    return {"wall_s": wall, "load_before": load0, "load_after": os.getloadavg()[0],
            "seq_s": [e["seconds"] for e in entries], "seq_cpu_s": [e["cpu_seconds"] for e in entries], "bytes": [e["bytes"] for e in entries],
            "nodes": len({e["node"] for e in entries}), "engine": summary["engine"]}


def _cpu_s() -> float:
    """CPU seconds of this process (all threads) and of its finished child processes (ffmpeg)."""
    import resource

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _store_round(store: str, frames: list[dict], size, folder: Path) -> dict:
    from vishap.scale.store import STREAMS, PngFrames, VideoFrames, make_sink

    n = len(frames)
    folder.mkdir(parents=True)
    load0, c0, t0 = os.getloadavg()[0], _cpu_s(), time.perf_counter()
    sink = make_sink(store, folder, size, 30.0)
    for i, f in enumerate(frames):
        sink.write(i, f)
    sink.close()
    write_s, write_cpu = time.perf_counter() - t0, _cpu_s() - c0
    nbytes = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    t0 = time.perf_counter()
    reader = PngFrames(folder) if store == "png" else VideoFrames(folder)
    back = [{s: reader.read(s, i) for s in STREAMS} for i in range(n)]
    read_s = time.perf_counter() - t0
    exact = len(reader) == n and all(np.array_equal(b[s], f[s]) for b, f in zip(back, frames) for s in STREAMS)
    return {"store": store, "bytes_per_frame": nbytes / n, "write_ms_per_frame": write_s / n * 1e3,
            "write_cpu_ms_per_frame": write_cpu / n * 1e3, "read_ms_per_frame": read_s / n * 1e3,
            "bit_exact": bool(exact), "load_before": load0, "load_after": os.getloadavg()[0]}


def _storage(args, tmp: Path) -> dict:
    """PNG against lossless video on the same rendered frames (see the module docstring)."""
    from vishap.sim.sequence import SequenceSpec, generate

    out = {}
    for res in [r for r in args.store_resolutions.split(",") if r]:
        w, h = (int(v) for v in res.lower().split("x"))
        spec = SequenceSpec(scene="wall", frames=args.store_frames, seed=0, width=w, height=h, start_s=1.0)
        frames = [{"left": pair.left, "right": pair.right, "labels/left": pair.labels_left,
                   "labels/right": pair.labels_right} for _, pair, _ in generate(spec)]
        rounds = {"png": [], "video": []}
        for r in range(args.store_rounds):
            for store in (("png", "video") if r % 2 == 0 else ("video", "png")):
                rounds[store].append(_store_round(store, frames, (w, h), tmp / f"store-{res}-{store}-{r}"))
        med = {st: {k: float(np.median([x[k] for x in rs]))
                    for k in ("bytes_per_frame", "write_ms_per_frame", "write_cpu_ms_per_frame", "read_ms_per_frame")}
               for st, rs in rounds.items()}
        out[res] = {"frames": args.store_frames, "rounds": rounds, "median": med,
                    "bit_exact": all(x["bit_exact"] for rs in rounds.values() for x in rs),
                    "video_size_vs_png": med["video"]["bytes_per_frame"] / med["png"]["bytes_per_frame"]}
    return out


def run(args) -> dict:
    import ray

    out = Path(args.out)
    jobs = _jobs(args)
    tmp = Path(tempfile.mkdtemp(prefix="bench-scale-"))
    try:
        storage = _storage(args, tmp)
        t0 = time.perf_counter()
        ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False, configure_logging=False)
        ray_start_s = time.perf_counter() - t0
        try:
            _build(jobs[:args.workers], tmp / "warm-ray", workers=args.workers)
            _build(jobs[:1], tmp / "warm-serial", workers=1)
            serial, parallel = [], []
            from vishap._core.results import progress

            for r in progress(range(args.rounds), desc="bench scale", unit="round", quiet=getattr(args, "quiet", False)):
                order = ("serial", "ray") if r % 2 == 0 else ("ray", "serial")
                for mode in order:
                    if mode == "serial":
                        serial.append(_build(jobs, tmp / f"serial-{r}", workers=1))
                    else:
                        parallel.append(_build(jobs, tmp / f"ray-{r}", workers=args.workers))
        finally:
            ray.shutdown()
        reference = _digests(tmp / "serial-0")
        identical = all(_digests(tmp / f"{m}-{r}") == reference for r in range(args.rounds) for m in ("serial", "ray"))
        cluster = _cluster(args, jobs, tmp, reference) if args.nodes > 1 else None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    t_serial = float(np.median([b["wall_s"] for b in serial]))
    t_par = float(np.median([b["wall_s"] for b in parallel]))
    ratios = [s["wall_s"] / p["wall_s"] for s, p in zip(serial, parallel)]
    seq_bytes = float(np.median([x for b in serial for x in b["bytes"]]))
    serial_cpu = float(np.median([x for b in serial for x in b["seq_cpu_s"]]))
    serial_seq_wall = float(np.median([x for b in serial for x in b["seq_s"]]))
    par_cpu = float(np.median([x for b in parallel for x in b["seq_cpu_s"]]))
    per_machine = args.seqs / t_par  # sequences per second
    stored = [x for st in storage.values() for rs in st["rounds"].values() for x in rs]
    loads = [b[k] for b in serial + parallel + ([cluster] if cluster else []) + stored for k in ("load_before", "load_after")]
    record = {
        "machine": machine_info(), "jobs": {"seqs": args.seqs, "frames": args.frames, "resolution": args.resolution,
                                            "scene": "wall", "effects": True},
        "ray_start_s": ray_start_s, "workers": args.workers,
        "serial": serial, "parallel": parallel,
        "serial_wall_s_median": t_serial, "parallel_wall_s_median": t_par,
        "speedup_median": t_serial / t_par, "speedup_per_round": ratios,
        "speedup_with_ray_start": t_serial / (t_par + ray_start_s),
        "serial_s_per_frame": t_serial / (args.seqs * args.frames),
        # CPU seconds per sequence (the rendering process, all its threads): the work each mode
        # does, whatever share of the cores the machine's load leaves it
        "serial_cpu_s_per_seq": serial_cpu, "parallel_cpu_s_per_seq": par_cpu,
        "serial_cores_busy": serial_cpu / serial_seq_wall,
        "parallel_s_per_frame": t_par / (args.seqs * args.frames),
        "bytes_identical": identical, "bytes_per_sequence": seq_bytes,
        "cluster": cluster,
        "projection": {
            "sequences": args.project,
            "hours_one_machine": args.project / per_machine / 3600,
            "hours_two_machines": args.project / (2 * per_machine) / 3600,
            "machines_per_1gbit_link": _LINK_BYTES_S / (per_machine * seq_bytes),
        },
        "storage": storage,
        "load_average": {"min": min(loads), "max": max(loads)},
    }
    if args.resolution in storage:  # sequences written as video travel that much smaller
        ratio = storage[args.resolution]["video_size_vs_png"]
        record["projection"]["machines_per_1gbit_link_video"] = _LINK_BYTES_S / (per_machine * seq_bytes * ratio)
    _chart(record, out)
    return record


def _cluster(args, jobs, tmp: Path, reference: dict) -> dict:
    import ray
    from ray.cluster_utils import Cluster

    t0 = time.perf_counter()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        for _ in range(args.nodes - 1):
            cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        start_s = time.perf_counter() - t0
        b = _build(jobs, tmp / "cluster", workers=None, address=cluster.address)
    finally:
        ray.shutdown()
        cluster.shutdown()
    b.update({"start_s": start_s, "nodes_started": args.nodes, "bytes_identical": _digests(tmp / "cluster") == reference})
    return b


def _chart(r: dict, out: Path) -> None:
    fig, (a, b, c) = new_figure(1, 3, figsize=(15, 4))
    names = ["1 (in process)", f"{r['workers']} Ray workers"]
    vals = [r["serial_wall_s_median"], r["parallel_wall_s_median"]]
    if r["cluster"]:
        names.append(f"{r['cluster']['nodes_started']}-node cluster\n(same machine)")
        vals.append(r["cluster"]["wall_s"])
    seqs = r["jobs"]["seqs"]
    a.bar(names, [seqs / v * 60 for v in vals], color=["0.6", "tab:blue", "tab:orange"][:len(vals)])
    for i, v in enumerate(vals):
        a.text(i, seqs / v * 60, f"{vals[0] / v:.2f}×", ha="center", va="bottom")
    a.set_ylabel("sequences per minute")
    a.set_title(f"{seqs} × {r['jobs']['frames']} frames at {r['jobs']['resolution']}, bytes identical: "
                f"{r['bytes_identical']}\nload average {r['load_average']['min']:.1f}–{r['load_average']['max']:.1f} "
                f"on {os.cpu_count()} cores", fontsize=9)
    p = r["projection"]
    machines = np.arange(1, 9)
    b.plot(machines, p["hours_one_machine"] / machines, "o-", label="ideal: throughput × machines")
    b.set_title(f"a 1 Gbit/s link into the driver carries {p['machines_per_1gbit_link']:.0f} such machines", fontsize=9)
    b.set_xlabel("machines like this one, at the throughput measured here")
    b.set_ylabel(f"hours for {p['sequences']} sequences")
    b.set_xlim(0.5, 8.5)
    b.legend(fontsize=8)
    for res, st in r["storage"].items():
        for store, marker in (("png", "o"), ("video", "s")):
            m = st["median"][store]
            c.scatter(m["write_ms_per_frame"], m["bytes_per_frame"] / 1e6, marker=marker,
                      color="0.5" if store == "png" else "tab:blue")
            c.annotate(f"{store} {res}\nread {m['read_ms_per_frame']:.0f} ms", (m["write_ms_per_frame"], m["bytes_per_frame"] / 1e6),
                       fontsize=7, xytext=(4, 4 if store == "png" else -18), textcoords="offset points")
    c.set_xlabel("write ms per frame (4 images, wall)")
    c.set_ylabel("MB per frame")
    c.set_title("storage: PNG vs lossless FFV1 video (bit-exact: "
                f"{all(st['bit_exact'] for st in r['storage'].values())})", fontsize=9)
    c.set_ylim(bottom=0)
    c.set_xlim(left=0)
    save_figure(fig, out / "scale_speedup.png")
