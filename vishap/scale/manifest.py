"""``manifest.json`` of a built data set: what was built, with which parameters, and a SHA-256 of
every file, so that a re-run can tell a finished sequence from a half-written or altered one.

Layout::

    {"format": "vishap-dataset/1", "command": "...", "parameters": {...},
     "sequences": {"seed-000003": {"parameters": {...}, "frames": 3, "bytes": 123456,
                                   "files": {"gt.npz": "<sha256>", "left/000000.png": "<sha256>", ...},
                                   "seconds": 1.9, "cpu_seconds": 2.7, "node": "<ray node id or 'local'>"}, ...}}

The manifest is rewritten (temporary file + rename) after every finished sequence.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from vishap._core.config import write_atomic
from vishap._core.errors import ConfigError

__all__ = ["FORMAT", "MANIFEST", "jsonable", "sha256", "file_hashes", "load_manifest", "save_manifest", "verify"]

FORMAT = "vishap-dataset/1"
MANIFEST = "manifest.json"


def jsonable(value):
    """``value`` as it reads back from JSON (tuples become lists), so parameters compare equal."""
    return json.loads(json.dumps(value, sort_keys=True))


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def file_hashes(folder: str | Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder``, keyed by its POSIX path relative to ``folder``."""
    folder = Path(folder)
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            out[p.relative_to(folder).as_posix()] = sha256(p.read_bytes())
    return out


def load_manifest(out: Path) -> dict | None:
    path = Path(out) / MANIFEST
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"cannot read the manifest ({exc})", file=path) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("sequences"), dict):
        raise ConfigError(f"not a data-set manifest (expected format {FORMAT!r})", file=path)
    return data


def save_manifest(out: Path, manifest: dict) -> None:
    write_atomic(Path(out) / MANIFEST, json.dumps(manifest, indent=1, sort_keys=True) + "\n")


def verify(folder: Path, entry: dict) -> bool:
    """Whether ``folder`` holds exactly the files of a manifest entry, with their checksums."""
    folder = Path(folder)
    if not folder.is_dir():
        return False
    want = entry.get("files", {})
    have = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    if have != sorted(want):
        return False
    return all(sha256((folder / k).read_bytes()) == v for k, v in want.items())
