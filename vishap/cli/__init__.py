"""The ``vishap`` command.

Each subcommand lives in its own module of this package and exposes ``register(subparsers)``,
which adds its parser and sets ``func`` (called with the parsed arguments, returning an exit
code). Modules are discovered, so adding a subcommand never edits this file.

What a command prints (:func:`vishap._core.results.show_result`, through :func:`report`): a
progress bar on stderr while it works (on a terminal, not with ``--quiet``), then a few readable
lines: the figures that matter and where the files are. The full record is saved as JSON in the
output folder; it goes to stdout, as one line, only with ``--json`` (:func:`add_json_flag`), so a
script asks for it explicitly.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Iterable

from vishap import __version__
from vishap._core.errors import VishapError
from vishap._core.results import progress_shown, show_result

__all__ = ["main", "build_parser", "report", "add_json_flag", "add_overwrite_flag", "add_quiet_flag", "quiet",
           "show_progress"]


def add_json_flag(parser: argparse.ArgumentParser) -> None:
    """``--json``: print the full record as one line of JSON instead of the summary."""
    parser.add_argument("--json", action="store_true",
                        help="print the full record as one line of JSON on stdout instead of the summary")


def add_overwrite_flag(parser: argparse.ArgumentParser, what: str = "--out") -> None:
    parser.add_argument("--overwrite", action="store_true", help=f"replace an existing {what} once this run is complete")


def add_quiet_flag(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quiet", action="store_true", help="no progress bar (there is none when stderr is not a terminal)")


def report(args: argparse.Namespace, record: dict, lines: Iterable[str] | None = None) -> None:
    """End a command: :func:`~vishap._core.results.show_result` with ``--json`` taken from ``args``."""
    show_result(record, lines, as_json=bool(getattr(args, "json", False)))


def quiet(args: argparse.Namespace) -> bool:
    """Whether the command was asked not to show progress (``--quiet``)."""
    return bool(getattr(args, "quiet", False))


def show_progress(args: argparse.Namespace) -> bool:
    """For library functions taking ``progress=``: a bar only on a terminal and without ``--quiet``."""
    return progress_shown(quiet(args))


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
