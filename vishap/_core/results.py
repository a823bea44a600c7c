"""Writing results: JSON-safe values, the machine a figure was measured on, charts on Agg, and what a
command shows on the terminal.

Shared by the apps (summary.json, plots), the benchmarks, the tactile plots and every command, so it
lives below them.

What a command shows: a progress bar with an ETA on stderr while it works (:func:`progress`: only
on a terminal, and not with ``--quiet``), then a few readable lines on stdout (:func:`show_result`:
the figures that matter and where the files are). The full record is saved as JSON in the output
folder and printed to stdout, as one line, only when asked (``--json``); its keys are the interface.
"""
from __future__ import annotations

import json
import math
import os
import platform
import sys
from collections.abc import Iterable
from pathlib import Path

import numpy as np

__all__ = ["to_jsonable", "machine_info", "new_figure", "save_figure", "record_json", "summary_lines", "show_result",
           "progress", "progress_shown"]


def to_jsonable(obj):
    """Convert numpy scalars/arrays (and NaN/inf, which JSON lacks) into plain JSON values."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def machine_info() -> dict:
    return {"python": platform.python_version(), "cpus": os.cpu_count(), "machine": platform.machine()}


def new_figure(*args, **kwargs):
    """A matplotlib figure on the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(*args, **kwargs)


def save_figure(fig, path: str | Path) -> Path:
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------- the terminal
def record_json(record: dict) -> str:
    """The record as one line of JSON (NaN/inf as null, numpy as plain values)."""
    return json.dumps(to_jsonable(record))


def summary_lines(record: dict, *, limit: int = 12) -> list[str]:
    """A generic summary when a command has none of its own: the record's numbers, flags and short
    text (top level first, then one level into its sub-records, as ``key.sub``), at most ``limit``
    lines, then the charts and files it names."""
    def scalar(v) -> bool:
        return isinstance(v, (int, float, bool, np.integer, np.floating, np.bool_)) or v is None or (
            isinstance(v, str) and len(v) <= 60 and not _is_file(v))

    def show(v) -> str:
        return f"{float(v):.4g}" if isinstance(v, (float, np.floating)) else str(v)

    figures = [(k, v) for k, v in record.items() if scalar(v)]
    figures += [(f"{k}.{kk}", vv) for k, v in record.items() if isinstance(v, dict) and k != "machine"
                for kk, vv in v.items() if scalar(vv)]
    lines = [f"  {k}: {show(v)}" for k, v in figures[:limit]]
    if len(figures) > limit:
        lines.append(f"  … {len(figures) - limit} more in the record")
    files = sorted({Path(f).name for f in _files(record)})
    if files:
        lines.append(f"  files: {', '.join(files)}")
    return lines


def _is_file(text: str) -> bool:
    return Path(text).suffix.lower() in {".png", ".json", ".csv", ".md", ".html", ".npz", ".mp4", ".wav", ".yaml"}


def _files(obj):
    if isinstance(obj, dict):
        for v in obj.values():
            yield from _files(v)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _files(v)
    elif isinstance(obj, str) and _is_file(obj):
        yield obj


def show_result(record: dict, lines: Iterable[str] | None = None, *, as_json: bool = False) -> None:
    """End a command: with ``as_json`` the record as one line of JSON on stdout, else ``lines``
    (default :func:`summary_lines`; a command's own lines say where its files are)."""
    if as_json:
        print(record_json(record))
        return
    for line in (summary_lines(record) if lines is None else lines):
        print(line)


def progress(iterable=None, *, total: int | None = None, desc: str, unit: str = "it", quiet: bool = False):
    """A tqdm progress bar with an ETA on stderr, shown only on a terminal and not when ``quiet``
    (a disabled bar still iterates and counts, so callers need no second code path)."""
    from tqdm import tqdm

    shown = progress_shown(quiet)
    # a terminal that reports a size of 0 (some containers' pseudo-terminals) would get no bar at all
    unsized = shown and _terminal_width(sys.stderr) == 0
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, disable=not shown,
                dynamic_ncols=not unsized, ncols=80 if unsized else None, nrows=24 if unsized else None,
                leave=False)


def _terminal_width(stream) -> int | None:
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, ValueError, OSError):  # not a real terminal (a test's capture)
        return None


def progress_shown(quiet: bool = False) -> bool:
    """Whether a progress bar is shown: stderr is a terminal and ``--quiet`` was not given (for the
    functions that take ``progress=`` and make their own bar)."""
    if quiet:
        return False
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # a closed or replaced stream
        return False
