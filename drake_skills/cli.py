"""The ``drake-skills`` command line.

Each subcommand lives in its own module under ``drake_skills.commands`` and
exposes ``register(subparsers)``, which adds its parser and sets ``func``. The
conventions (``--out`` is a directory, ``--seed`` only where something is random)
are in :mod:`drake_skills.commands`. The global flags (``-v``, ``--version``) are
accepted before or after any command and subcommand; every command and subcommand
has a description (its ``help`` if it gives none).

Library warnings (:class:`~drake_skills.library.views.DataWarning`: a motion without
its workspace, data in other units) are printed as ``drake-skills: warning: ...``.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
import warnings

# Module names under drake_skills.commands, in the order --help lists them.
COMMAND_MODULES = [
    "demo",
    "learn",
    "recognize",
    "import_data",
    "generate",
    "plot_demos",
    "evaluate",
    "tune",
    "bench",
    "control",
]


def _version() -> str:
    from drake_skills import __version__

    return f"drake-skills {__version__}"


def _global_flags(parser: argparse.ArgumentParser, *, top: bool) -> None:
    """``-v`` and ``--version``; below the top level their default is SUPPRESS, so a flag given
    before the command is not reset by the subcommand's own default."""
    default = False if top else argparse.SUPPRESS
    parser.add_argument("-v", "--verbose", action="store_true", default=default, help="log debug messages")
    parser.add_argument("--version", action="version", version=_version(), help="print the version and exit")


class _SubParsers(argparse._SubParsersAction):
    """Sub-parsers that accept the global flags and always have a description."""

    def add_parser(self, name, **kwargs):
        kwargs.setdefault("description", kwargs.get("help"))
        parser = super().add_parser(name, **kwargs)
        parser.register("action", "parsers", _SubParsers)
        _global_flags(parser, top=False)
        return parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="drake-skills",
        description="Learn an open-ended library of collaborative skills (Interaction ProMPs) from demonstrations, "
                    "one at a time, and run it as a Drake controller. `drake-skills COMMAND --help` describes a "
                    "command. --out is always a directory (default ./out/COMMAND), rewritten on every run.")
    parser.register("action", "parsers", _SubParsers)
    _global_flags(parser, top=True)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"drake_skills.commands.{name}")
        except Exception as exc:  # a broken command is an error, never a silently missing command
            raise RuntimeError(f"drake-skills: the command module drake_skills.commands.{name} failed to import "
                               f"({type(exc).__name__}: {exc})") from exc
        module.register(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Library data warnings as one plain line; any other warning as Python prints it."""
    from drake_skills.library.views import DataWarning

    if issubclass(category, DataWarning):
        print(f"drake-skills: warning: {message}", file=sys.stderr if file is None else file)
    else:
        _default_show(message, category, filename, lineno, file, line)


_default_show = warnings.showwarning


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    out = getattr(args, "out", None)
    if out is not None and os.path.exists(out) and not os.path.isdir(out):
        print(f"drake-skills {args.command}: error: --out '{out}' is a file, not a directory", file=sys.stderr)
        return 1
    shown = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, FileExistsError) as exc:
        print(f"drake-skills {args.command}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        warnings.showwarning = shown


if __name__ == "__main__":
    sys.exit(main())
