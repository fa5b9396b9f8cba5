"""The shared data files tests read in place (``../shared/data`` beside the repository, or ``$DRAKE_SKILLS_SHARED``).

A test that needs one calls :func:`require`: it skips, with a reason naming the missing path,
only when the file is absent and ``DRAKE_SKILLS_REQUIRE_DATA`` is unset (or empty or 0); with
``DRAKE_SKILLS_REQUIRE_DATA=1`` (``.ci/run`` sets it) a missing file fails the test.
"""
import os
from pathlib import Path

import pytest

from drake_skills.data.interaction import SHARED_ENV, shared_data_path

REQUIRE_ENV = "DRAKE_SKILLS_REQUIRE_DATA"


def required() -> bool:
    return os.environ.get(REQUIRE_ENV, "") not in ("", "0")


def require(name: str = "buetepage_hr.npz") -> Path:
    """The path of a shared data file; skip (or fail, when required) if it is missing."""
    path = shared_data_path(name)
    if not path.is_file():
        msg = (f"shared data file {path} is missing (put the shared folder beside the repository or set "
               f"{SHARED_ENV})")
        if required():
            pytest.fail(f"{msg}, and {REQUIRE_ENV}={os.environ[REQUIRE_ENV]} requires it")
        pytest.skip(msg)
    return path
