"""The ``drake-skills`` command line.

Each subcommand lives in its own module under ``drake_skills.commands`` and
exposes ``register(subparsers)``, which adds its parser and sets ``func``.
Every command has ``--help``, ``--seed`` and ``--out`` (default
``./out/<command>``).
"""
from __future__ import annotations

import argparse
import importlib
import logging
import sys

# Module names under drake_skills.commands, in the order --help lists them.
COMMAND_MODULES = [
    "demo",
    "learn",
    "recognize",
    "generate",
    "plot_demos",
    "evaluate",
    "tune",
    "bench",
    "control",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="drake-skills",
        description="Learn an open-ended library of collaborative skills (Interaction ProMPs) "
                    "from demonstrations, one at a time, and run it as a Drake controller.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"drake_skills.commands.{name}")
        except Exception as exc:  # a broken command is an error, never a silently missing command
            raise RuntimeError(f"drake-skills: the command module drake_skills.commands.{name} failed to import "
                               f"({type(exc).__name__}: {exc})") from exc
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"drake-skills {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
