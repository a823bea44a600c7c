"""Where tasks run: in this process (one worker, no cluster), on a local Ray instance with N workers,
or on an existing Ray cluster given by its address (issue 18).

An address that cannot be reached is an error (:class:`ClusterError`) and the run stops: work meant
for a cluster never falls back to this machine silently. Ray's own connection attempt to a dead
address retries for minutes, so the address is first probed with a plain TCP connection.

Every Ray task runs with ``LP_NUM_THREADS`` set to the CPUs the task holds (llvmpipe, the CPU
OpenGL renderer, otherwise starts one thread per core in every worker and N workers oversubscribe
the machine N times).
"""
from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from vishap._core.errors import ConfigError, VishapError

__all__ = ["ClusterError", "Engine", "engine", "map_cases", "parse_address", "probe", "worker_env"]

_PROBE_TIMEOUT_S = 5.0


class ClusterError(VishapError, RuntimeError):
    """A Ray cluster cannot be reached or refused the work."""


def parse_address(address: str) -> tuple[str, int] | None:
    """``(host, port)`` of a ``HOST:PORT`` or ``ray://HOST:PORT`` address; ``None`` for ``auto``."""
    if address == "auto":
        return None
    text = address.removeprefix("ray://")
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError(f"expected HOST:PORT, ray://HOST:PORT or auto, got {address!r}", field="address")
    return host.strip("[]"), int(port)


def probe(address: str) -> None:
    """Raise :class:`ClusterError` unless a TCP connection to ``address`` opens within 5 s."""
    hp = parse_address(address)
    if hp is None:
        return
    try:
        with socket.create_connection(hp, timeout=_PROBE_TIMEOUT_S):
            pass
    except OSError as exc:
        raise ClusterError(f"cannot reach the Ray cluster at {address} ({exc.strerror or exc}); "
                           f"nothing was run (start the cluster or fix --address)") from None


def worker_env(threads: int) -> dict[str, str]:
    """Environment of a render worker holding ``threads`` CPUs."""
    n = str(max(1, int(threads)))
    return {"LP_NUM_THREADS": n, "OMP_NUM_THREADS": n}


@dataclass
class Engine:
    """A place to run tasks. ``workers``: how many tasks run at once; ``ray``: ``None`` when they run
    one after another in this process, else the connected :mod:`ray` module."""

    workers: int
    threads_per_worker: int
    address: str | None
    ray: Any = None

    @property
    def local(self) -> bool:
        return self.ray is None

    def describe(self) -> dict:
        out = {"workers": self.workers, "threads_per_worker": self.threads_per_worker,
               "mode": "in-process" if self.ray is None else ("cluster" if self.address else "local-ray")}
        if self.address:
            out["address"] = self.address
        if self.ray is not None:
            out["nodes"] = sum(1 for n in self.ray.nodes() if n.get("Alive"))
            out["cluster_cpus"] = sum(n["Resources"].get("CPU", 0.0) for n in self.ray.nodes() if n.get("Alive"))
        return out

    def remote(self, fn: Callable, **options):
        """``fn`` as a Ray remote function holding ``threads_per_worker`` CPUs, renderer threads pinned."""
        return self.ray.remote(fn).options(
            num_cpus=self.threads_per_worker,
            runtime_env={"env_vars": worker_env(self.threads_per_worker)}, **options)


@contextlib.contextmanager
def _own_local_instance() -> Iterator[None]:
    """Let ``ray.init`` start an instance of this run's own: without an address Ray joins the instance
    that ``RAY_ADDRESS`` or the last ``ray start`` on this machine names, and then refuses a CPU count.
    ``address="local"`` covers the second; ``RAY_ADDRESS`` outranks even that, so it is set aside
    while Ray starts (a cluster is asked for with ``--address``)."""
    saved = os.environ.pop("RAY_ADDRESS", None)
    try:
        yield
    finally:
        if saved is not None:
            os.environ["RAY_ADDRESS"] = saved


@contextlib.contextmanager
def engine(workers: int | None = None, address: str | None = None, *, threads_per_worker: int = 1) -> Iterator[Engine]:
    """Open a place to run tasks (see the module docstring).

    ``workers=1`` without ``address``: in this process, no Ray. ``workers=N > 1``: a local Ray
    instance with N CPUs, shut down on exit. ``address``: an existing cluster (``HOST:PORT``,
    ``ray://HOST:PORT`` or ``auto``); ``workers`` then caps the tasks in flight (default: the
    cluster's CPUs / ``threads_per_worker``). If Ray is already initialised by the caller, that
    session is used and left running.
    """
    if workers is not None and int(workers) < 1:
        raise ConfigError(f"workers must be >= 1, got {workers}", field="workers")
    if int(threads_per_worker) < 1:
        raise ConfigError(f"threads per worker must be >= 1, got {threads_per_worker}", field="threads_per_worker")
    if address is None and (workers is None or int(workers) == 1):
        yield Engine(1, int(threads_per_worker), None, None)
        return
    import ray

    owned = not ray.is_initialized()
    if owned:
        common = dict(log_to_driver=False, configure_logging=False, include_dashboard=False)
        if address is not None:
            probe(address)
            try:
                ray.init(address=address, **common)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                raise ClusterError(f"cannot connect to the Ray cluster at {address} ({exc}); nothing was run") from None
        else:
            with _own_local_instance():
                ray.init(address="local", num_cpus=int(workers) * int(threads_per_worker), **common)
    try:
        if workers is None:
            # the nodes' own records: the cluster's resource view lags behind a node that just joined
            cpus = sum(n["Resources"].get("CPU", 0.0) for n in ray.nodes() if n.get("Alive"))
            workers = max(1, int(cpus // int(threads_per_worker)))
        yield Engine(int(workers), int(threads_per_worker), address, ray)
    finally:
        if owned:
            ray.shutdown()


def _call(fn, case):
    return fn(case)


def map_cases(fn: Callable[[Any], Any], cases: Sequence, *, workers: int = 1, address: str | None = None,
              threads_per_worker: int = 1, progress: bool = False, desc: str = "cases") -> list:
    """``[fn(c) for c in cases]``, with the cases run as Ray tasks when ``workers > 1`` or ``address``.

    Results come back in the order of ``cases`` and equal a serial run's as long as ``fn`` depends
    only on its case (seeds in the case, not global state). ``fn`` and the cases must pickle
    (a module-level function). One progress bar counts finished cases over all workers.
    """
    from vishap._core.results import progress as progress_bar

    cases = list(cases)
    if not cases:  # nothing to run: no Ray start, but a bad address is still an error
        if address is not None:
            probe(address)
        return []
    with engine(workers, address, threads_per_worker=threads_per_worker) as eng:
        bar = progress_bar(total=len(cases), desc=desc, unit="case", quiet=not progress)
        try:
            if eng.local:
                out = []
                for c in cases:
                    out.append(fn(c))
                    bar.update(1)
                return out
            task = eng.remote(_call)
            fn_ref = eng.ray.put(fn)
            results: list = [None] * len(cases)
            pending: dict = {}
            todo = iter(enumerate(cases))
            for i, c in todo:
                pending[task.remote(fn_ref, c)] = i
                if len(pending) >= eng.workers:
                    break
            while pending:
                done, _ = eng.ray.wait(list(pending), num_returns=1)
                for ref in done:
                    results[pending.pop(ref)] = eng.ray.get(ref)
                    bar.update(1)
                for i, c in todo:
                    pending[task.remote(fn_ref, c)] = i
                    break
            return results
        finally:
            bar.close()
