"""Output folders written all at once: a temporary sibling, renamed into place at the end.

Every command that writes a folder (``--out``) goes through :func:`output_dir`::

    with output_dir(args.out, overwrite=args.overwrite) as out:
        write_everything_into(out.path)       # a hidden sibling of args.out
    # here args.out holds the complete result, or it was never touched

What it guarantees:

* a non-empty ``--out`` is refused unless ``overwrite``; ``--out`` onto a file, into a read-only
  folder or under a file is one :class:`~vishap._core.errors.ConfigError` naming the path;
* on an error, Ctrl-C (SIGINT) or SIGTERM, the temporary folder is removed, and so are the parent
  folders this call created *if they are still empty*: nothing another run or the user made is
  deleted, and ``--out`` keeps what it held;
* with ``overwrite``, the old ``--out`` is swapped out only once the new one is complete;
* two runs into one ``--out``: the second to finish does not replace the first; its result is kept
  beside it (``OUT-2``) and it fails saying so.
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from vishap._core.errors import ConfigError

__all__ = ["output_dir", "OutputFolder", "check_output_folder", "check_output_file", "sigterm_as_exit"]


@dataclass
class OutputFolder:
    """``path``: where to write now (temporary); ``final``: where the result will be."""

    path: Path
    final: Path

    def relocate(self, text: str) -> str:
        """``text`` with the temporary folder's path replaced by the final one (for records)."""
        return text.replace(str(self.path), str(self.final))


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _missing_parents(p: Path) -> list[Path]:
    """The ancestors of ``p`` that do not exist yet, outermost first."""
    missing = []
    for q in p.parents:
        if q.exists():
            break
        missing.append(q)
    return missing[::-1]


def check_output_folder(path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """The checks :func:`output_dir` makes, without creating anything: for a command that works a
    long time before it writes, so that a bad ``--out`` is refused before the work starts."""
    out = Path(path).absolute()
    _check_target(out, overwrite)
    return out


def _check_target(out: Path, overwrite: bool) -> None:
    for q in out.parents:
        if q.exists() and not q.is_dir():
            raise ConfigError(f"cannot write the output folder: {q} is a file", file=out)
        if q.exists():
            if not os.access(q, os.W_OK | os.X_OK):
                raise ConfigError(f"cannot write the output folder: {q} is not writable", file=out)
            break
    if out.exists() or out.is_symlink():
        if not out.is_dir():
            raise ConfigError("output exists and is not a folder", file=out)
        if any(out.iterdir()):
            if not overwrite:
                raise ConfigError("output folder exists and is not empty (pass --overwrite to replace it)", file=out)
            cwd = Path.cwd().resolve()
            real = out.resolve()
            if real == Path(real.anchor) or real == Path.home().resolve() or real == cwd or real in cwd.parents:
                raise ConfigError("refusing to replace this folder (the root, home or current folder, or one "
                                  "holding it); choose a dedicated output folder", file=out)


@contextlib.contextmanager
def sigterm_as_exit() -> Iterator[None]:
    """Within the block, SIGTERM raises ``SystemExit(143)`` so that cleanup code runs (as SIGINT's
    KeyboardInterrupt does); outside the main thread nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _raise(signum, frame):
        raise SystemExit(128 + signum)

    try:
        previous = signal.signal(signal.SIGTERM, _raise)
    except ValueError:  # not in the main interpreter
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _remove_if_empty(folders: list[Path]) -> None:
    for q in reversed(folders):  # innermost first
        with contextlib.suppress(OSError):
            q.rmdir()  # only succeeds when empty: never removes what another run put there


def _free_sibling(out: Path) -> Path:
    k = 2
    while True:
        cand = out.with_name(f"{out.name}-{k}")
        if not cand.exists():
            return cand
        k += 1


@contextlib.contextmanager
def output_dir(path: str | os.PathLike, *, overwrite: bool = False) -> Iterator[OutputFolder]:
    """Write a folder atomically; see the module docstring."""
    out = Path(path).absolute()
    _check_target(out, overwrite)
    created = _missing_parents(out)
    with sigterm_as_exit():
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
        except OSError as exc:
            _remove_if_empty(created)
            raise ConfigError(f"cannot write the output folder ({_reason(exc)})", file=out) from None
        try:
            yield OutputFolder(tmp, out)
            _commit(tmp, out, overwrite)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            _remove_if_empty(created)
            raise


def _commit(tmp: Path, out: Path, overwrite: bool) -> None:
    os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700; the result is an ordinary folder
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            keep = _free_sibling(out)
            tmp.rename(keep)
            raise ConfigError(f"another run wrote this folder meanwhile; this run's output is in {keep}", file=out)
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
        try:
            out.rename(old / "x")
            tmp.rename(out)
        finally:
            shutil.rmtree(old, ignore_errors=True)  # ``old`` is ours; it holds what --overwrite replaces
        return
    try:
        tmp.rename(out)  # onto a missing or empty folder
    except OSError as exc:
        if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
            keep = _free_sibling(out)
            tmp.rename(keep)
            raise ConfigError(f"another run wrote this folder meanwhile; this run's output is in {keep}",
                              file=out) from None
        raise ConfigError(f"cannot write the output folder ({_reason(exc)})", file=out) from None


def _umask() -> int:
    from vishap._core.config import _umask as umask

    return umask()


def check_output_file(path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Check that a single output file can be written: not a folder, its folder writable, and not
    an existing file unless ``overwrite``. The write itself goes through ``write_atomic``."""
    p = Path(path).absolute()
    if p.is_dir():
        raise ConfigError("is a folder, expected a file path", file=p)
    if p.exists() and not overwrite:
        raise ConfigError("file exists (pass --overwrite to replace it)", file=p)
    for q in p.parents:
        if q.exists():
            if not q.is_dir():
                raise ConfigError(f"cannot write here: {q} is a file", file=p)
            if not os.access(q, os.W_OK | os.X_OK):
                raise ConfigError(f"cannot write here: {q} is not writable", file=p)
            break
    return p
