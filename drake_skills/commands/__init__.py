"""One module per ``drake-skills`` subcommand; see ``drake_skills.cli``."""
from __future__ import annotations

import argparse
from pathlib import Path


def add_common(parser: argparse.ArgumentParser, command: str, *, seed: int = 0) -> None:
    """Add the options every command has: ``--seed`` and ``--out``."""
    parser.add_argument("--seed", type=int, default=seed, help=f"random seed (default {seed})")
    parser.add_argument("--out", type=Path, default=Path("out") / command,
                        help=f"directory for artifacts (default ./out/{command})")
