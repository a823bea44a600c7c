"""Configuration files (YAML or TOML) validated on load.

Configuration is data: rigs, scenes, devices and tactile settings live in files. A schema is a
pydantic model; :func:`load_config` reads a file, validates it against the model and turns the
first problem into one :class:`~vishap._core.errors.ConfigError` that names the file and the field.
"""
from __future__ import annotations

import os
import tempfile
import tomllib
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from vishap._core.errors import ConfigError

__all__ = ["Schema", "read_mapping", "load_config", "validate", "write_atomic"]

M = TypeVar("M", bound=BaseModel)


class Schema(BaseModel):
    """Base of every configuration schema: unknown keys are errors, values are checked on assignment."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False)


def read_mapping(path: str | os.PathLike) -> dict[str, Any]:
    """Read a YAML (``.yaml``/``.yml``) or TOML (``.toml``) file whose top level is a mapping."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("file not found", file=path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read file ({exc})", file=path) from None
    try:
        if path.suffix.lower() == ".toml":
            data = tomllib.loads(text)
        else:
            data = yaml.safe_load(text)
    except (yaml.YAMLError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"not valid {'TOML' if path.suffix.lower() == '.toml' else 'YAML'} ({exc})".replace("\n", " "), file=path) from None
    if data is None:
        raise ConfigError("file is empty", file=path)
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, got {type(data).__name__}", file=path)
    return data


def _field_path(loc: tuple) -> str:
    return ".".join(str(p) for p in loc) if loc else "<top level>"


def validate(model: type[M], data: Any, *, file: str | os.PathLike | None = None) -> M:
    """Validate ``data`` against ``model``; the first problem becomes a :class:`ConfigError`."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        msg = err.get("msg", "invalid value")
        if "input" in err and err.get("type") != "missing":
            msg = f"{msg} (got {err['input']!r})"
        raise ConfigError(msg, file=file, field=_field_path(err.get("loc", ()))) from None


def load_config(path: str | os.PathLike, model: type[M]) -> M:
    """Read ``path`` (YAML or TOML) and validate it against ``model``."""
    return validate(model, read_mapping(path), file=path)


def write_atomic(path: str | os.PathLike, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` through a temporary file and a rename: never a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = "wb" if isinstance(data, bytes) else "w"
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path
