"""Where the tests find the real data kept beside the project (``../shared/data``), never copied into it."""
import os
from pathlib import Path

import pytest

#: ``../shared/data`` from the project root (see its README.md).
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BUETEPAGE_HR = SHARED_DATA / "buetepage_hr.npz"


def require(path: Path) -> Path:
    """``path`` if it exists; else skip, or fail when DRAKE_SKILLS_REQUIRE_DATA is set (as in CI)."""
    if path.is_file():
        return path
    message = f"the data file {path} is missing (it is read from ../shared/data beside the project)"
    if os.environ.get("DRAKE_SKILLS_REQUIRE_DATA"):
        pytest.fail(message + " and DRAKE_SKILLS_REQUIRE_DATA is set")
    pytest.skip(message + "; set DRAKE_SKILLS_REQUIRE_DATA=1 to make this a failure")
