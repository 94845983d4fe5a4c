"""Shared pytest fixtures. Keep this minimal: fixtures used by one file live in that file."""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
# The suite's caches (generated rooms' meshes, imports) in a folder of its own, removed at the end,
# not in the user's ~/.cache/illumix (a generated room writes ~3 MB of meshes there)
if "ILLUMIX_CACHE" not in os.environ:
    os.environ["ILLUMIX_CACHE"] = tempfile.mkdtemp(prefix="illumix-test-cache-")
    atexit.register(shutil.rmtree, os.environ["ILLUMIX_CACHE"], True)
try:
    import illumix_client  # noqa: F401
except ImportError:  # the client is not installed yet: its tests use the source tree
    # (tests/test_client.py's test_distribution_installed says to install it)
    sys.path.insert(0, str(REPO_ROOT / "clients" / "python"))
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
