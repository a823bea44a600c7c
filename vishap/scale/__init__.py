"""Scale-out: synthetic sequences and benchmark cases as Ray tasks, in this process, on a local Ray
instance with N workers, or on an existing cluster (issue 18).

- :func:`map_cases` — ``[fn(c) for c in cases]`` on N workers, ordered, equal to a serial run.
- :func:`build_sequences` — many sequences under one folder with ``manifest.json``, resumable.
- :func:`engine` — the place tasks run; :class:`ClusterError` when a cluster can't be reached.
"""
from vishap.scale.engine import ClusterError, Engine, engine, map_cases
from vishap.scale.sequences import Job, build_sequences, seed_folder, spec_parameters

__all__ = ["ClusterError", "Engine", "engine", "map_cases", "Job", "build_sequences", "seed_folder", "spec_parameters"]
