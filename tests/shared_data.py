"""The project's shared data beside the checkout (``../shared``: SocialGym 2.0's map folders,
recorded crowds): a test that needs it skips, naming the folder, where it is missing, and fails
where ``SGJAX_REQUIRE_SHARED=1`` says this run must have it (``.ci/run`` sets it, as CI always
has ``../shared``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"
SG2MAPS = SHARED / "sg2maps"  # SocialGym 2.0's real map folders
REQUIRE = "SGJAX_REQUIRE_SHARED"


def require(path: Path, what: str) -> Path:
    """``path`` if it exists; else skip (or fail under ``SGJAX_REQUIRE_SHARED=1``) naming it."""
    if path.exists():
        return path
    reason = f"{what} not at {path} (the shared data folder beside the checkout)"
    if os.environ.get(REQUIRE) == "1":
        pytest.fail(f"{reason}; {REQUIRE}=1: this run must have it")
    pytest.skip(reason)
    return path  # pragma: no cover - skip raises
