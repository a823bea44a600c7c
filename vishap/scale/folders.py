"""Folders as values: what a task wrote, read into ``{relative path: bytes}`` so that it travels back
through Ray's object store (the nodes of a cluster share no file system with the command), and
written into place atomically by the command."""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

__all__ = ["read_files", "commit_files", "remove_leftovers"]

_UMASK = os.umask(0o022)
os.umask(_UMASK)
_DIR_MODE = 0o777 & ~_UMASK


def read_files(folder: str | Path) -> dict[str, bytes]:
    """Every file under ``folder``, keyed by its POSIX path relative to ``folder``, in sorted order."""
    folder = Path(folder)
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def commit_files(out: str | Path, rel: str, files: dict[str, bytes]) -> Path:
    """Write ``files`` into ``out/rel`` atomically: a hidden temporary sibling, then a rename (an
    existing ``out/rel`` is replaced only once the new one is complete)."""
    final = Path(out) / rel
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.tmp-", dir=final.parent))
    try:
        for name, data in files.items():
            p = tmp / name
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(data)
        tmp.chmod(_DIR_MODE)  # a data set is shared: the umask's mode, not mkdtemp's private 0700
        if final.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{final.name}.old-", dir=final.parent))
            final.rename(old / "x")
            tmp.rename(final)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final


def remove_leftovers(out: str | Path, rel: str) -> None:
    """The temporary folders of ``out/rel`` that a killed run left (call it only under a lock that
    says no other run is writing there)."""
    final = Path(out) / rel
    if final.parent.is_dir():
        for p in final.parent.glob(f".{final.name}.tmp-*"):
            shutil.rmtree(p, ignore_errors=True)
        for p in final.parent.glob(f".{final.name}.old-*"):
            shutil.rmtree(p, ignore_errors=True)
