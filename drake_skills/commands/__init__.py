"""One module per ``drake-skills`` subcommand; see ``drake_skills.cli``.

The conventions every command follows (the README's "Command line" says the same):

* ``--out DIR`` is always a directory, default ``./out/<command>``; a command writes its
  files inside it under fixed names (``learn``: ``DIR/library.npz``), creating it if
  needed, and rewrites all of them on every run, so that nothing left from an earlier
  run can be taken for this one's.
* An existing input is named by its own option or argument (``learn --library LIB``
  extends a library, ``recognize LIB PATH...``), never by ``--out``.
* ``--seed`` only where something is random (the presentation order of ``learn``, the
  simulated data and trials of ``generate``, ``demo`` and ``eval``).
* ``-v`` (debug messages) is accepted before or after the command.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_out(parser: argparse.ArgumentParser, command: str, what: str = "artifacts") -> None:
    """Add ``--out DIR`` (default ``./out/<command>``)."""
    parser.add_argument("--out", type=Path, default=Path("out") / command, metavar="DIR",
                        help=f"directory for {what} (default ./out/{command}); rewritten on every run")


def clear_reports(out: Path, names) -> None:
    """Remove an earlier run's reports ``names`` from ``out`` before this run starts.

    A run that fails must not leave the previous run's reports looking like its own (the
    README's convention: nothing from an earlier run is left to be taken for this one).
    Only reports: a library in ``out`` is an input or refused, never removed here.
    """
    for name in names:
        path = Path(out) / name
        if path.is_file():
            path.unlink()


def add_seed(parser: argparse.ArgumentParser, seed: int | None = 0, seed_help: str | None = None) -> None:
    """Add ``--seed``; ``seed=None`` leaves it unset unless given (e.g. to keep a config file's seed)."""
    parser.add_argument("--seed", type=int, default=seed, help=seed_help or f"random seed (default {seed})")


def add_common(parser: argparse.ArgumentParser, command: str, *, seed: int | None = 0,
               seed_help: str | None = None) -> None:
    """Add ``--seed`` and ``--out`` (for commands where something is random)."""
    add_seed(parser, seed, seed_help)
    add_out(parser, command)


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


#: Files that give the workspace of the demonstrations in their folder, in order of preference.
WORKSPACE_FILES = ("workspace.json", "calibration.npz")


def add_workspace(parser: argparse.ArgumentParser) -> None:
    """Add ``--workspace FILE`` (a workspace.json or a calibration .npz for every file)."""
    parser.add_argument("--workspace", "--calibration", dest="workspace", type=Path, default=None, metavar="FILE",
                        help="workspace.json ({\"lower\", \"upper\", \"scale\"}) or calibration .npz for every "
                             "file (default: the nearest workspace.json or calibration.npz in the file's folder "
                             "or above it, up to the folder given)")


class WorkspaceFinder:
    """The workspace of each demonstration file: one given for all, or found beside it.

    Looks for :data:`WORKSPACE_FILES` in the file's folder, then in each parent up to
    and including ``root``; each workspace file is read once.
    """

    def __init__(self, given: Path | None, root: Path):
        from drake_skills.data.demos import load_workspace

        self._load = load_workspace
        self._given = None if given is None else (load_workspace(given), Path(given))
        self._root = Path(root).resolve()
        self._cache: dict[Path, object] = {}

    def __call__(self, demo_file) -> tuple:
        """``(Workspace or None, the file it came from or None)``."""
        if self._given is not None:
            return self._given
        folder = Path(demo_file).resolve().parent
        while True:
            for name in WORKSPACE_FILES:
                f = folder / name
                if f.is_file():
                    if f not in self._cache:
                        self._cache[f] = self._load(f)
                    return self._cache[f], f
            if folder == self._root or self._root not in folder.parents:
                return None, None
            folder = folder.parent


def scan_paths(paths: list[Path], *, failed: list | None = None):
    """Demonstration files named, or found in the folders named: ``[(demo, root)]`` and the notes.

    A folder is scanned with :func:`drake_skills.data.demos.scan_dir` (each demonstration
    once, non-demonstration files skipped with a note); its files' workspaces are looked
    for up to that folder. A file is read as it is; its workspace is looked for beside it.
    ``failed``: a list that collects ``(path, error)`` of the files that cannot be read,
    instead of raising on the first (``recognize --keep-going``).
    """
    from drake_skills.data.demos import load_demo, scan_dir

    out, notes = [], []
    for p in paths:
        p = Path(p)
        if p.is_dir():
            scan = scan_dir(p, keep_going=failed is not None)
            notes += scan.notes()
            out += [(d, p) for d in scan.demos]
            if failed is not None:
                failed += scan.failed
        elif p.is_file():
            try:
                out.append((load_demo(p), p.parent))
            except ValueError as exc:
                if failed is None:
                    raise
                failed.append((p, str(exc)))
        else:
            raise FileNotFoundError(f"'{p}' does not exist")
    return out, notes


def tasks_file(library: Path) -> Path:
    """The sidecar of a library file that holds its components' task labels: ``<stem>.tasks.json``."""
    library = Path(library)
    return library.with_name(library.stem + ".tasks.json")


def short_name(name: str | None, root: Path) -> str:
    """``name`` relative to ``root`` when it lies inside it (for tables), else as it is."""
    if not name:
        return "?"
    try:
        return str(Path(name).resolve().relative_to(Path(root).resolve()))
    except ValueError:
        return name
