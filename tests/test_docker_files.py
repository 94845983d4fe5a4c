"""The container images copy every package of the project (docker/Dockerfile.*).

The images install the repository's packages from COPY'd folders, not from git: a package added to
``pyproject.toml`` but not copied installs fine and fails only at run time, in the container (the
service imports ``imagefiles`` for ``format=dng|exr``; the CLI registers every command). The images
are built by ``docker/smoke.sh``, outside CI, so this is checked here as text.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _packages() -> set[str]:
    """The repository folders pyproject.toml installs (``package-dir``: ``illumix.<room>`` → ``<room>``)."""
    folders = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"].values()
    return {f for f in folders if (ROOT / f / "__init__.py").is_file()}


@pytest.mark.parametrize("dockerfile", ["Dockerfile.service", "Dockerfile.render"])
def test_every_package_is_copied_into_the_image(dockerfile):
    text = (ROOT / "docker" / dockerfile).read_text()
    copied = set(re.findall(r"^COPY (\w+) /build/src/\1$", text, re.MULTILINE))
    missing = _packages() - copied
    assert not missing, f"docker/{dockerfile} does not COPY {sorted(missing)} into /build/src"


def test_every_package_is_in_the_build_context():
    """``.dockerignore`` leaves out everything but what it lists: a package COPY'd but not listed is
    not in the build context, and the build fails."""
    allowed = set(re.findall(r"^!(\w+)/$", (ROOT / ".dockerignore").read_text(), re.MULTILINE))
    missing = _packages() - allowed
    assert not missing, f".dockerignore does not let {sorted(missing)} into the build context"
