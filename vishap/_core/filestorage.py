"""Reading OpenCV FileStorage YAML without OpenCV: the ``%YAML:1.0`` header, ``!!opencv-matrix``.

``cv2.FileStorage`` trusts the file: a matrix node without ``cols:`` or with ``rows:`` twice makes
its reader corrupt memory (SIGSEGV/SIGABRT now and then), and junk after the header raises
``SystemError``. This reader parses the same files with the project's YAML reader
(:func:`vishap._core.config.read_yaml_text`) and checks every matrix node (exactly ``rows``,
``cols``, ``dt``, ``data``; ``rows × cols`` finite numbers) before anything uses it, so a bad file
is one :class:`~vishap._core.errors.ConfigError` naming the file and the node. Writing stays with
``cv2.FileStorage``, whose files OpenCV's own tools read.

Several documents in one file (``cat intrinsics.yml extrinsics.yml``, as OpenCV's stereo sample
writes them) are merged; a node given twice is an error.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from vishap._core.config import ProjectLoader, read_text, read_yaml_text
from vishap._core.errors import ConfigError

__all__ = ["read_filestorage", "parse_filestorage", "MATRIX_TAG"]

MATRIX_TAG = "tag:yaml.org,2002:opencv-matrix"
_MATRIX_KEYS = ("rows", "cols", "dt", "data")
_DT = set("ucwsifdh")  # OpenCV depth codes: 8u, 8s, 16u, 16s, 32s, 32f, 64f, 16f
_MAX_SIDE = 64  # no matrix of a calibration file is larger
_DIRECTIVE = re.compile(r"^%YAML[: ]\s*\d+\.\d+\s*$")


class _Matrix(dict):
    """A ``!!opencv-matrix`` mapping, checked and converted after parsing."""


class _FileStorageLoader(ProjectLoader):
    pass


def _construct_matrix(loader, node):
    if not isinstance(node, yaml.MappingNode):
        raise yaml.constructor.ConstructorError(None, None, "!!opencv-matrix must be a mapping of rows, cols, dt, data",
                                                node.start_mark)
    return _Matrix(loader.construct_mapping(node, deep=True))


_FileStorageLoader.yaml_constructors = dict(ProjectLoader.yaml_constructors)
_FileStorageLoader.yaml_constructors[MATRIX_TAG] = _construct_matrix


def _matrix(node: _Matrix, field: str, file) -> np.ndarray:
    keys = set(node)
    for k in _MATRIX_KEYS:
        if k not in keys:
            raise ConfigError(f"!!opencv-matrix lacks '{k}:' (needs rows, cols, dt and data)", file=file, field=field)
    extra = sorted(str(k) for k in keys - set(_MATRIX_KEYS))
    if extra:
        raise ConfigError(f"!!opencv-matrix has unexpected keys {extra}", file=file, field=field)
    rows, cols, dt, data = (node[k] for k in _MATRIX_KEYS)
    for name, v in (("rows", rows), ("cols", cols)):
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= _MAX_SIDE:
            raise ConfigError(f"'{name}' must be an integer in 1..{_MAX_SIDE}, got {v!r}", file=file, field=field)
    if not isinstance(dt, str) or dt not in _DT:
        raise ConfigError(f"'dt' must be one of OpenCV's depth codes {''.join(sorted(_DT))}, got {dt!r}",
                          file=file, field=field)
    if not isinstance(data, list) or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in data):
        raise ConfigError("'data' must be a list of numbers", file=file, field=field)
    if len(data) != rows * cols:
        raise ConfigError(f"'data' has {len(data)} values, rows × cols = {rows} × {cols} needs {rows * cols}",
                          file=file, field=field)
    arr = np.array(data, dtype=np.float64).reshape(rows, cols)
    if not np.all(np.isfinite(arr)):  # ints beyond the float range become inf here
        raise ConfigError("contains NaN or inf", file=file, field=field)
    return arr


def parse_filestorage(text: str, *, file: str | os.PathLike | None = None) -> dict[str, Any]:
    """Parse the text of a FileStorage YAML file into plain values and ``(rows, cols)`` float64 arrays."""
    stripped = text.lstrip("\ufeff \t\r\n")
    if stripped.startswith("<?xml"):
        raise ConfigError("an XML FileStorage file: save it as YAML (cv2.FileStorage with a .yaml name)", file=file)
    if not stripped.startswith("%YAML"):
        raise ConfigError("not an OpenCV FileStorage file (expected a '%YAML:1.0' header)", file=file)
    # OpenCV's ':' form of the directive is not YAML: blank every directive line (line numbers stay)
    lines = ["" if _DIRECTIVE.match(line) else line for line in stripped.splitlines()]
    docs = read_yaml_text("\n".join(lines), file=file, loader=_FileStorageLoader, documents=True)
    out: dict[str, Any] = {}
    for doc in docs:
        if doc is None:
            continue
        if not isinstance(doc, dict):
            raise ConfigError(f"top level must be a mapping, got {type(doc).__name__}", file=file)
        for key, value in doc.items():
            key = str(key)
            if key in out:
                raise ConfigError("node given twice", file=file, field=key)
            out[key] = _matrix(value, key, file) if isinstance(value, _Matrix) else value
    if not out:
        raise ConfigError("file holds no nodes", file=file)
    for key, value in out.items():
        if isinstance(value, (dict, list)) and _holds_matrix(value):
            raise ConfigError("!!opencv-matrix nested inside another node is not read", file=file, field=key)
    return out


def _holds_matrix(value) -> bool:
    stack = [value]
    while stack:
        v = stack.pop()
        if isinstance(v, _Matrix):
            return True
        if isinstance(v, dict):
            stack.extend(v.values())
        elif isinstance(v, list):
            stack.extend(v)
    return False


def read_filestorage(path: str | os.PathLike) -> dict[str, Any]:
    """Read a FileStorage YAML file; see :func:`parse_filestorage`."""
    path = Path(path)
    text = read_text(path)
    return parse_filestorage(text, file=path)
