"""Configuration files (YAML, TOML or JSON) read by one validated reader.

Configuration is data: rigs, scenes, devices and tactile settings live in files. Every file the
package reads goes through :func:`read_mapping` (or :func:`read_yaml_text` for text already in
memory), which guarantees that

* nothing but a :class:`~vishap._core.errors.ConfigError` naming the file escapes it, whatever the
  bytes (bad syntax, unknown or malformed tags such as ``!!timestamp 2024-13-45``, deep nesting,
  alias bombs, binary junk);
* the result holds only mappings, lists, strings, booleans, ``None``, integers and *finite* floats:
  NaN, infinity and numbers beyond the float range are refused with the field named;
* ``1e5`` is a number (YAML 1.2), not the string YAML 1.1 makes of it, and dates stay strings.

A schema is a pydantic model (:class:`Schema`: unknown keys and non-finite floats are errors);
:func:`load_config` reads a file, validates it against the model and turns the first problem into
one :class:`ConfigError` that names the file and the field. Loaders that check by hand wrap their
checks in :func:`reading` so that a slip there still ends as a ConfigError naming the file.
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import re
import tempfile
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from vishap._core.errors import ConfigError, VishapError

__all__ = [
    "Schema",
    "read_mapping",
    "read_yaml_text",
    "read_text",
    "ProjectLoader",
    "check_tree",
    "load_config",
    "validate",
    "reading",
    "write_atomic",
    "MAX_FILE_BYTES",
    "MAX_DEPTH",
]

M = TypeVar("M", bound=BaseModel)

#: Largest configuration file read (bytes): the biggest file the project ships is a few kilobytes.
MAX_FILE_BYTES = 16 * 1024 * 1024
#: Deepest nesting of mappings/lists accepted; the project's files nest at most 5 levels.
MAX_DEPTH = 64
#: Most values (after aliases are expanded) one file may hold: an alias bomb stops here.
MAX_NODES = 1_000_000


class Schema(BaseModel):
    """Base of every configuration schema: unknown keys are errors, values are checked on
    assignment, and a float field refuses NaN and infinity."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False, allow_inf_nan=False)


# ---------------------------------------------------------------------------------------- YAML
_FLOAT_12 = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


class ProjectLoader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 exponents (``1e5`` is a float), no implicit dates, no tags that
    build anything but plain data, and a nesting limit checked before the recursion it guards."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def construct_mapping(self, node, deep=False):
        # a key given twice is a mistake PyYAML would hide by keeping the last value
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge" or not isinstance(key_node, yaml.ScalarNode):
                    continue
                if key_node.value in seen:
                    raise yaml.constructor.ConstructorError(None, None, f"key {key_node.value!r} is given twice",
                                                            key_node.start_mark)
                seen.add(key_node.value)
        return super().construct_mapping(node, deep=deep)

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise yaml.YAMLError(f"nesting deeper than {MAX_DEPTH} levels (line {mark.line + 1})")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


ProjectLoader.yaml_implicit_resolvers = {
    k: [(tag, rx) for tag, rx in v if tag != "tag:yaml.org,2002:timestamp"]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
ProjectLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))
ProjectLoader.yaml_constructors = dict(yaml.SafeLoader.yaml_constructors)


def _refuse_tag(loader, node):
    raise yaml.constructor.ConstructorError(None, None, f"tag {node.tag} is not allowed in a configuration file",
                                            node.start_mark)


for _tag in ("timestamp", "binary", "set", "omap", "pairs"):
    ProjectLoader.yaml_constructors[f"tag:yaml.org,2002:{_tag}"] = _refuse_tag
ProjectLoader.yaml_constructors[None] = _refuse_tag  # any unknown tag


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).replace('in "<unicode string>", ', "").split())
    return text[:300] or type(exc).__name__


def read_yaml_text(text: str, *, file: str | os.PathLike | None = None, loader: type | None = None,
                   documents: bool = False) -> Any:
    """Parse YAML ``text`` with the project's loader (or a subclass of it) and check the result
    with :func:`check_tree`; any problem is one :class:`ConfigError` naming ``file``.

    With ``documents``, every document of a multi-document stream is returned, as a list.
    """
    try:
        if documents:
            data = list(yaml.load_all(text, Loader=loader or ProjectLoader))  # noqa: S506 - a SafeLoader subclass
        else:
            data = yaml.load(text, Loader=loader or ProjectLoader)  # noqa: S506 - a SafeLoader subclass
    except VishapError:
        raise
    except RecursionError:
        raise ConfigError(f"not valid YAML (nesting deeper than {MAX_DEPTH} levels)", file=file) from None
    except Exception as exc:  # yaml errors, and whatever a constructor raises (ValueError, OverflowError…)
        raise ConfigError(f"not valid YAML ({_one_line(exc)})", file=file) from None
    for doc in data if documents else [data]:
        check_tree(doc, file=file)
    return data


def check_tree(data: Any, *, file: str | os.PathLike | None = None) -> Any:
    """Refuse anything but plain data with finite numbers, too deep a nesting or too many values.

    Returns ``data`` unchanged. The field of the first bad value is named as a dotted path.
    """
    count = 0
    stack: list[tuple[Any, tuple, int]] = [(data, (), 0)]
    while stack:
        value, loc, depth = stack.pop()
        count += 1
        if count > MAX_NODES:
            raise ConfigError(f"more than {MAX_NODES} values (aliases expanded)", file=file)
        field = ".".join(str(p) for p in loc) or None
        if isinstance(value, bool) or value is None or isinstance(value, str):
            continue
        if isinstance(value, float):
            if not math.isfinite(value):
                raise ConfigError(f"NaN or infinity is not allowed (got {value})", file=file, field=field)
            continue
        if isinstance(value, int):
            if abs(value) > 2**1023:
                raise ConfigError("number beyond the float range", file=file, field=field)
            continue
        if isinstance(value, (dict, list)):
            if depth >= MAX_DEPTH:
                raise ConfigError(f"nesting deeper than {MAX_DEPTH} levels", file=file,
                                  field=".".join(str(p) for p in loc[:4]) + "...")
            items = value.items() if isinstance(value, dict) else enumerate(value)
            for k, v in items:
                if isinstance(value, dict) and not isinstance(k, (str, int, bool)) and k is not None:
                    raise ConfigError(f"a key must be a name, got {type(k).__name__}", file=file, field=field)
                stack.append((v, (*loc, k), depth + 1))
            continue
        raise ConfigError(f"unsupported value of type {type(value).__name__}", file=file, field=field)
    return data


# ---------------------------------------------------------------------------------------- files
def read_text(path: str | os.PathLike) -> str:
    """The UTF-8 text of a configuration file no larger than :data:`MAX_FILE_BYTES`; a missing,
    unreadable, binary or huge file is one :class:`ConfigError` naming it."""
    path = Path(path)
    try:
        if not path.is_file():
            raise ConfigError("file not found" if not path.exists() else "not a file", file=path)
        if path.stat().st_size > MAX_FILE_BYTES:
            raise ConfigError(f"larger than {MAX_FILE_BYTES // 2**20} MiB: not a configuration file", file=path)
        return path.read_bytes().decode("utf-8")
    except VishapError:
        raise
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"cannot read file ({_one_line(exc)})", file=path) from None


def read_mapping(path: str | os.PathLike) -> dict[str, Any]:
    """Read a YAML (``.yaml``/``.yml``), TOML (``.toml``) or JSON (``.json``) file whose top level is
    a mapping; see the module docstring for what is guaranteed."""
    path = Path(path)
    text = read_text(path)
    suffix = path.suffix.lower()
    if suffix in (".toml", ".json"):
        kind = suffix[1:].upper()
        try:
            data = tomllib.loads(text) if suffix == ".toml" else json.loads(text)
        except RecursionError:
            raise ConfigError(f"not valid {kind} (nesting too deep)", file=path) from None
        except Exception as exc:
            raise ConfigError(f"not valid {kind} ({_one_line(exc)})", file=path) from None
        check_tree(data, file=path)
    else:
        data = read_yaml_text(text, file=path)
    if data is None:
        raise ConfigError("file is empty", file=path)
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, got {type(data).__name__}", file=path)
    return data


def _field_path(loc: tuple) -> str:
    return ".".join(str(p) for p in loc) if loc else "<top level>"


@contextlib.contextmanager
def reading(file: str | os.PathLike | None, field: str | None = None) -> Iterator[None]:
    """Turn any exception but a :class:`VishapError` raised inside into a :class:`ConfigError`
    naming ``file`` (and ``field``): the guarantee of one error kind for code that checks by hand."""
    try:
        yield
    except ConfigError as exc:
        if exc.file is None and file is not None:
            raise type(exc)(exc.reason, file=file, field=exc.field or field) from None
        raise
    except VishapError:
        raise
    except RecursionError:
        raise ConfigError("nesting too deep", file=file, field=field) from None
    except Exception as exc:  # a malformed value that slipped past the checks (TypeError, KeyError…)
        raise ConfigError(f"invalid content ({type(exc).__name__}: {_one_line(exc)})", file=file, field=field) from None


def validate(model: type[M], data: Any, *, file: str | os.PathLike | None = None) -> M:
    """Validate ``data`` against ``model``; the first problem becomes a :class:`ConfigError`."""
    with reading(file):
        try:
            return model.model_validate(data)
        except ValidationError as exc:
            err = exc.errors()[0]
            msg = err.get("msg", "invalid value")
            if "input" in err and err.get("type") != "missing":
                msg = f"{msg} (got {_short_repr(err['input'])})"
            raise ConfigError(msg, file=file, field=_field_path(err.get("loc", ()))) from None


def _short_repr(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 120 else text[:117] + "..."


def load_config(path: str | os.PathLike, model: type[M]) -> M:
    """Read ``path`` (YAML, TOML or JSON) and validate it against ``model``."""
    return validate(model, read_mapping(path), file=path)


def _umask() -> int:
    """The process's umask, read without changing it where the system allows (Linux)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_atomic(path: str | os.PathLike, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` through a temporary file and a rename: never a half-written file.

    The file gets the mode an ordinary ``open(path, "w")`` would give it (0666 less the umask,
    so 0644 or 0664 usually): calibrations are shared with the user's group, not private.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_dir():
            raise ConfigError("is a folder, expected a file path", file=path)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except VishapError:
        raise
    except OSError as exc:
        raise ConfigError(f"cannot write here ({exc.strerror or exc})", file=path) from None
    mode = "wb" if isinstance(data, bytes) else "w"
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, mode) as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise ConfigError(f"cannot write here ({exc.strerror or exc})", file=path) from None
        raise
    return path
