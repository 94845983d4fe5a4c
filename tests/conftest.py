"""Shared pytest fixtures. Keep this minimal: fixtures used by one file live in that file."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
# Measured data (rawtoaces cameras, ISETCam reflectances) lives beside the repository, never in it.
SHARED = REPO_ROOT.parent / "shared"
SHARED_DATA = SHARED / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` next to the repository root; tests needing it skip when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"measured data folder {SHARED_DATA} is absent (it sits beside the repository, "
                    "see DESIGN.md 'Conventions')")
    return SHARED_DATA
