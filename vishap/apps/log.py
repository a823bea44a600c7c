"""``log.npz``: every signal of a demo run, grouped by the loop that produced it.

A run records into a :class:`SignalLog`: one :class:`Channel` per loop (``servo`` at 1 kHz,
``vision`` per camera frame, ``scene`` at 60 Hz, ``tactile`` at 1 kHz, ``events``), each a set of
equally long arrays keyed ``"<channel>/<signal>"`` in the NPZ. ``meta`` holds the run's
configuration, rig and calibration as JSON, so that ``vishap replay`` can rebuild every stage.
Camera frames are not in the NPZ: they are PNG files beside it (``frames/left|right/NNNNNN.png``,
the layout ``vishap synth`` writes), lossless so that replay sees the exact pixels.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["Channel", "SignalLog", "load_log", "write_frame_png", "read_frame_png", "code_version"]


def code_version() -> dict:
    """Which code made a log: the git commit of the checkout holding ``vishap`` (and whether it had
    uncommitted changes) and ``stages_sha256``, a digest of the code and data of the stages a
    replay re-runs (vision, world, tactile and the apps themselves)."""
    import hashlib
    import subprocess

    import vishap

    root = Path(vishap.__file__).resolve().parent
    out: dict = {"version": vishap.__version__}
    try:
        out["git"] = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                    timeout=5).stdout.strip() or None
        out["dirty"] = bool(subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no",
                                            "--", "."], capture_output=True, text=True, timeout=5).stdout.strip())
    except (OSError, subprocess.SubprocessError):
        out["git"], out["dirty"] = None, None
    h = hashlib.sha256()
    for sub in ("_core", "vision", "world", "runtime", "tactile", "apps"):
        for f in sorted((root / sub).rglob("*")):
            if f.suffix in (".py", ".yaml", ".yml", ".npz", ".json", ".toml") and "__pycache__" not in f.parts:
                h.update(f.relative_to(root).as_posix().encode())
                h.update(f.read_bytes())
    out["stages_sha256"] = h.hexdigest()[:16]
    return out


class Channel:
    """Rows of named signals appended one sample at a time; ``arrays()`` stacks them."""

    def __init__(self) -> None:
        self._rows: dict[str, list] = {}
        self._n = 0

    def append(self, **values) -> None:
        if self._n and set(values) != set(self._rows):
            missing = set(self._rows) ^ set(values)
            raise ValueError(f"channel row has different signals than before: {sorted(missing)}")
        for k, v in values.items():
            self._rows.setdefault(k, []).append(v)
        self._n += 1

    def __len__(self) -> int:
        return self._n

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self._rows.items()}


class SignalLog:
    """All channels of a run plus its metadata."""

    def __init__(self, meta: dict | None = None) -> None:
        self.meta: dict = dict(meta or {})
        self.channels: dict[str, Channel] = {}

    def channel(self, name: str) -> Channel:
        ch = self.channels.get(name)
        if ch is None:
            ch = self.channels[name] = Channel()
        return ch

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"meta": np.array(json.dumps(self.meta, default=_json_default))}
        for cname, ch in self.channels.items():
            for k, v in ch.arrays().items():
                out[f"{cname}/{k}"] = v
        return out

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **self.to_arrays())
        return path


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def load_log(path: str | Path) -> tuple[dict, dict[str, dict[str, np.ndarray]]]:
    """Read a ``log.npz`` (or a run folder holding one) → ``(meta, {channel: {signal: array}})``."""
    path = Path(path)
    if path.is_dir():
        path = path / "log.npz"
    if not path.is_file():
        raise ConfigError("log not found (expected a demo's log.npz or its output folder)", file=path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"not a readable NPZ log ({exc})", file=path) from None
    if "meta" not in data:
        raise ConfigError("missing 'meta' (not a vishap demo log)", file=path, field="meta")
    meta = json.loads(str(data.pop("meta")))
    channels: dict[str, dict[str, np.ndarray]] = {}
    for key, arr in data.items():
        cname, _, sig = key.partition("/")
        channels.setdefault(cname, {})[sig] = arr
    return meta, channels


def write_frame_png(folder: Path, side: str, index: int, image: np.ndarray) -> None:
    import cv2

    d = folder / side
    d.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(d / f"{index:06d}.png"), image, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
        raise OSError(f"cannot write {d / f'{index:06d}.png'}")


def read_frame_png(folder: Path, side: str, index: int) -> np.ndarray:
    import cv2

    p = folder / side / f"{index:06d}.png"
    img = cv2.imread(str(p), cv2.IMREAD_COLOR)
    if img is None:
        raise ConfigError("frame image missing or unreadable", file=p)
    return img
