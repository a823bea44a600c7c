"""Build many synthetic sequences at once, resumably (issue 18, items 1 and 2).

Each sequence is one job: a relative folder name (``seed-000003``, ``wall/seed-000012``) and a
:class:`~vishap.sim.sequence.SequenceSpec`. A worker renders it with
:func:`vishap.sim.writer.write_sequence` (the function behind ``vishap synth --seed S``, so the
bytes are the same) into its own temporary folder and sends the files back through Ray's object
store: the nodes of a cluster need no shared file system. This process writes each sequence into a
hidden temporary sibling of its folder, renames it into place, then records its files' SHA-256 in
``manifest.json``.

A re-run with the same jobs skips every sequence whose folder matches its manifest entry and
redoes the others: a folder missing from the manifest (the run stopped between the rename and
the manifest), one whose files differ from their checksums, and the temporary folders a killed run
left behind. A job whose parameters differ from the manifest's entry is an error: a sequence that
another set of parameters made is never replaced. One lock per output folder keeps two builds out
of each other's way.
"""
from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import os
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from vishap._core.errors import ConfigError
from vishap.scale.engine import engine, probe
from vishap.scale.folders import commit_files, read_files, remove_leftovers
from vishap.scale.manifest import FORMAT, MANIFEST, jsonable, load_manifest, save_manifest, sha256, verify

__all__ = ["Job", "spec_parameters", "render_files", "build_sequences", "seed_folder"]

LOCK = ".vishap-build.lock"
_POLL_S = 0.5


def seed_folder(seed: int) -> str:
    return f"seed-{int(seed):06d}"


@dataclass(frozen=True)
class Job:
    """One sequence: ``rel`` its folder under the output, ``spec`` what to render, ``parameters``
    what the manifest records of it (JSON) and compares on a re-run."""

    rel: str
    spec: object
    parameters: dict


def spec_parameters(spec, *, rig_sha256: str | None = None) -> dict:
    """The manifest's record of a :class:`SequenceSpec`: every field, the rig as its file's SHA-256."""
    d = {f.name: getattr(spec, f.name) for f in dataclasses.fields(spec) if f.name not in ("rig", "T_robot_cam")}
    if d.get("store") == "png":
        del d["store"]  # the default layout: manifests written before there was a choice still match
    if d.get("exposure_s") is None:
        d.pop("exposure_s", None)  # the camera model's own exposure: likewise
    if spec.rig is not None:
        d["rig_sha256"] = rig_sha256 or "in-memory"
    if spec.T_robot_cam is not None:
        d["T_robot_cam"] = [[float(v) for v in row] for row in spec.T_robot_cam]
    return jsonable(d)


def check_spec(spec) -> int:
    """Everything about ``spec`` that can fail before rendering; returns its frame count."""
    from vishap.sim.hand import skin_tone_rgb
    from vishap.sim.sequence import prepare
    from vishap.sim.textures import choose_background

    p = prepare(spec)
    choose_background(spec.background, spec.seed)
    if spec.skin_tone is not None:
        skin_tone_rgb(spec.skin_tone)
    return len(p.times)


def render_files(spec, report: Callable[[int], None] | None = None) -> dict:
    """Render one sequence with :func:`~vishap.sim.writer.write_sequence` in a temporary folder and
    return its files: ``{"files": {relpath: bytes}, "sha256": {relpath: hex}, "seconds": s, "cpu_seconds": s}``
    (CPU time of the whole process, the renderer's threads included)."""
    from vishap.sim.writer import write_sequence

    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory(prefix="vishap-seq-") as tmp:
        files = read_files(write_sequence(Path(tmp) / "seq", spec, on_frame=report))
    return {"files": files, "sha256": {k: sha256(v) for k, v in files.items()}, "seconds": time.perf_counter() - t0,
            "cpu_seconds": time.process_time() - c0}


def _render_task(spec, key: str, progress) -> dict:
    """:func:`render_files` inside a Ray worker: OpenCV's threads pinned like llvmpipe's, progress
    sent to the driver's counter actor, the node recorded."""
    import os

    import cv2
    import ray

    cv2.setNumThreads(int(os.environ.get("LP_NUM_THREADS", "1")))
    out = render_files(spec, report=lambda n: progress.set.remote(key, n))
    out["node"] = ray.get_runtime_context().get_node_id()
    return out


class _Progress:
    """Frames written so far by each running job (a Ray actor the workers report to)."""

    def __init__(self):
        self.frames: dict[str, int] = {}

    def set(self, key: str, n: int) -> None:
        self.frames[key] = n

    def drop(self, key: str) -> None:
        self.frames.pop(key, None)

    def total(self) -> int:
        return sum(self.frames.values())


@contextlib.contextmanager
def _locked(out: Path):
    f = open(out / LOCK, "a")
    try:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise ConfigError("another build is writing into this folder", file=out) from None
        yield
    finally:
        f.close()


def _first_difference(a: dict, b: dict) -> str:
    for k in sorted(set(a) | set(b)):
        if a.get(k) != b.get(k):
            return f"{k}: built with {a.get(k)!r}, asked for {b.get(k)!r}"
    return ""


def _plan(jobs: Sequence[Job], out: Path, manifest: dict) -> tuple[list[Job], list[str]]:
    todo, skipped = [], []
    for job in jobs:
        entry = manifest["sequences"].get(job.rel)
        if entry is not None and entry.get("parameters") != job.parameters:
            raise ConfigError(f"{job.rel} was built with other parameters ({_first_difference(entry.get('parameters', {}), job.parameters)}); "
                              "use another output folder", file=out / MANIFEST, field=f"sequences.{job.rel}")
        remove_leftovers(out, job.rel)
        if entry is not None and verify(out / job.rel, entry):
            skipped.append(job.rel)
        else:
            todo.append(job)
    return todo, skipped


def build_sequences(jobs: Sequence[Job], out: str | Path, *, workers: int | None = 1, address: str | None = None,
                    threads_per_worker: int = 1, command: str = "synth", parameters: dict | None = None,
                    progress: bool = True) -> dict:
    """Render ``jobs`` under ``out`` (see the module docstring); returns a summary
    (``built``, ``skipped``, ``seconds``, ``engine``)."""
    from tqdm import tqdm

    rels = [j.rel for j in jobs]
    if len(set(rels)) != len(rels):
        raise ConfigError("two sequences would be written into the same folder", field="seeds")
    frames = {j.rel: check_spec(j.spec) for j in jobs}
    if address is not None:
        probe(address)  # before anything is written
    out = Path(out).absolute()
    if out.exists() and not out.is_dir():
        raise ConfigError("output exists and is not a folder", file=out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the output folder ({exc.strerror or exc})", file=out) from None
    with _locked(out):
        manifest = load_manifest(out)
        if manifest is None:
            if any(p.name != LOCK for p in out.iterdir()):
                raise ConfigError(f"output folder is not empty and has no {MANIFEST} (not a build of this kind)", file=out)
            manifest = {"format": FORMAT, "sequences": {}}
        manifest["command"] = command
        manifest["parameters"] = jsonable(parameters or {})
        todo, skipped = _plan(jobs, out, manifest)
        t0 = time.perf_counter()
        bar = tqdm(total=sum(frames[j.rel] for j in todo), desc=command, unit="frame", disable=not progress)

        def finished(job: Job, res: dict) -> None:
            commit_files(out, job.rel, res["files"])
            manifest["sequences"][job.rel] = {
                "parameters": job.parameters, "frames": frames[job.rel], "files": res["sha256"],
                "bytes": sum(len(v) for v in res["files"].values()), "seconds": round(res["seconds"], 3),
                "cpu_seconds": round(res["cpu_seconds"], 3),
                "node": res.get("node", "local")}
            save_manifest(out, manifest)

        try:
            with engine(workers if todo else 1, address, threads_per_worker=threads_per_worker) as eng:
                if eng.local:
                    _run_here(todo, frames, bar, finished)
                else:
                    _run_ray(eng, todo, frames, bar, finished)
                desc = eng.describe()
        finally:
            bar.close()
        save_manifest(out, manifest)
    return {"out": str(out), "built": [j.rel for j in todo], "skipped": skipped,
            "seconds": time.perf_counter() - t0, "engine": desc}


def _run_here(todo, frames, bar, finished) -> None:
    done = 0
    for job in todo:
        def report(n, base=done):
            bar.n = base + n
            bar.refresh()
        res = render_files(job.spec, report=report if not bar.disable else None)
        done += frames[job.rel]
        bar.n = done
        bar.refresh()
        finished(job, res)


def _run_ray(eng, todo, frames, bar, finished) -> None:
    ray = eng.ray
    counter = ray.remote(num_cpus=0)(_Progress).remote()
    task = eng.remote(_render_task, max_retries=0)
    pending: dict = {}
    queue = iter(todo)
    done = 0

    def submit() -> None:
        for job in queue:
            pending[task.remote(job.spec, job.rel, counter)] = job
            return

    for _ in range(eng.workers):
        submit()
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1, timeout=_POLL_S)
        for ref in ready:
            job = pending.pop(ref)
            res = ray.get(ref)
            counter.drop.remote(job.rel)
            done += frames[job.rel]
            finished(job, res)
            submit()
        if not bar.disable:
            # a late report may arrive after its job was dropped: never show more than the total
            bar.n = min(bar.total, done + ray.get(counter.total.remote()))
            bar.refresh()
