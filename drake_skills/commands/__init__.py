"""One module per ``drake-skills`` subcommand; see ``drake_skills.cli``."""
from __future__ import annotations

import argparse
from pathlib import Path


def add_common(parser: argparse.ArgumentParser, command: str, *, seed: int | None = 0,
               seed_help: str | None = None) -> None:
    """Add the options every command has: ``--seed`` and ``--out``.

    ``seed=None`` leaves ``--seed`` unset unless given (e.g. to keep a config file's seed).
    """
    parser.add_argument("--seed", type=int, default=seed, help=seed_help or f"random seed (default {seed})")
    parser.add_argument("--out", type=Path, default=Path("out") / command,
                        help=f"directory for artifacts (default ./out/{command})")


def add_config(parser: argparse.ArgumentParser) -> None:
    """Add ``--config``: a YAML of SimConfig or LibraryConfig fields (see ``drake_skills.sim.config``)."""
    parser.add_argument("--config", type=Path, default=None, metavar="YAML",
                        help="YAML file: SimConfig fields (drake_skills.sim.config; library settings under "
                             "'library:', the gating under 'decision:'), or LibraryConfig fields alone "
                             "(drake_skills.library.config); default: the defaults")
