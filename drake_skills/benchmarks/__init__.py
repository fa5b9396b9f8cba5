"""Speed measurements (not tests), run with ``drake-skills bench``.

Every module here with a ``run(quick: bool = False, config=None) -> list[dict]``
function is a suite; the command discovers them, so adding ``sim.py`` needs no
registration. ``config`` is the ``SimConfig`` of ``--config`` (None: the suite's own
settings); suites that build no library ignore it. Rows are flat dicts with at
least a ``name``.
"""
from __future__ import annotations

import importlib
import pkgutil
from typing import Callable


def discover_suites() -> dict[str, Callable[..., list[dict]]]:
    """``{suite name: run}`` for every module of this package that has a ``run`` function."""
    suites = {}
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        run = getattr(module, "run", None)
        if callable(run):
            suites[info.name] = run
    return suites
