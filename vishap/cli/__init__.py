"""The ``vishap`` command.

Each subcommand lives in its own module of this package and exposes ``register(subparsers)``,
which adds its parser and sets ``func`` (called with the parsed arguments, returning an exit
code). Modules are discovered, so adding a subcommand never edits this file.

What a command prints: :func:`report` writes a short readable summary when stdout is a terminal,
and the command's record as one line of JSON when asked (``--json``, see :func:`add_json_flag`)
or when stdout is a pipe or a file, so scripts keep reading JSON. Commands that write a folder
also save the record there.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import pkgutil
import sys
from collections.abc import Iterable
from pathlib import Path

from vishap import __version__
from vishap._core.errors import VishapError

__all__ = ["main", "build_parser", "report", "add_json_flag", "add_overwrite_flag", "record_lines"]


def add_json_flag(parser: argparse.ArgumentParser) -> None:
    """``--json``: print the record as one line of JSON even on a terminal."""
    parser.add_argument("--json", action="store_true", help="print the record as one line of JSON")


def add_overwrite_flag(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")


def _jsonable(obj):
    from vishap.bench._common import to_jsonable

    return to_jsonable(obj)


def record_lines(record: dict, *, limit: int = 12) -> list[str]:
    """A generic summary: the record's top-level numbers, text and flags, one per line."""
    lines = []
    for k, v in record.items():
        if isinstance(v, float):
            lines.append(f"  {k}: {v:.4g}")
        elif isinstance(v, (int, str, bool)) or v is None:
            lines.append(f"  {k}: {v}")
        if len(lines) >= limit:
            lines.append("  …")
            break
    return lines


def report(args: argparse.Namespace, record: dict, lines: Iterable[str] | None = None, *,
           save_to: str | os.PathLike | None = None) -> None:
    """Print a command's result: ``lines`` (default :func:`record_lines`) on a terminal, the JSON
    record with ``--json`` or when stdout is not a terminal; with ``save_to``, also write the
    record there (atomically)."""
    from vishap._core.config import write_atomic

    text = json.dumps(_jsonable(record))
    if save_to is not None:
        write_atomic(save_to, text + "\n")
    if getattr(args, "json", False) or not sys.stdout.isatty():
        print(text)
        return
    for line in (record_lines(record) if lines is None else lines):
        print(line)
    if save_to is not None:
        print(f"  record: {Path(save_to)}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vishap",
        description="Vision-centric, encountered-type augmented-reality haptics.",
    )
    parser.add_argument("--version", action="version", version=f"vishap {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    func = getattr(args, "func", None)
    if func is None:  # bare ``vishap`` (or a group without its action): usage, not success
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(func(args) or 0)
    except VishapError as exc:
        print(f"vishap {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"vishap {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
