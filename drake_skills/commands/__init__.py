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


def add_subjects_model(parser: argparse.ArgumentParser, *, from_config: bool = False) -> None:
    """Add ``--subjects-model``: how the simulated salad subjects move (drake_skills.scenario.salad).

    ``from_config=True`` leaves it unset unless given (the ``--config`` file's model then holds).
    """
    from drake_skills.sim.config import SUBJECT_MODELS

    default = SUBJECT_MODELS[0]
    parser.add_argument("--subjects-model", choices=SUBJECT_MODELS, default=None if from_config else default,
                        help="simulated subjects: 'styled' (people who differ in how they move) or 'classic' "
                             "(one task geometry scaled per person, the first model); default "
                             + (f"the config's, {default}" if from_config else default))
