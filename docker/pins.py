#!/usr/bin/env python3
"""Version pins for the images: write ``docker/constraints.txt``, or check an image against it.

``python docker/pins.py freeze [--extras render,ray] [--also PKG,...] [--out docker/constraints.txt]``
    Run in a working environment where ``illumix`` and its extras are installed and tested (e.g.
    after ``bash scripts/install.sh --test && pip install -e '.[ray]'``). Reads the requirements of
    ``pyproject.toml`` (base + the given extras), follows them through the *installed* packages'
    metadata (markers evaluated for this interpreter, requested extras followed) and writes
    ``name==version`` for every package reached — the ``pip freeze`` pins of exactly what the images
    install — plus the build tools (pip, setuptools). Editable/local projects are left out.
    ``--also`` follows more top-level requirements, e.g. ``s3fs`` for images built with
    ``EXTRA_PACKAGES=s3fs``.

``python docker/pins.py check CONSTRAINTS``
    Run inside an image after ``pip install -c CONSTRAINTS …``: fails (exit 1) when an installed
    distribution is missing from the constraints or has another version, so an image never carries an
    unpinned package.

The freeze mode needs ``packaging`` (present wherever pip is); check needs the standard library only.
"""

from __future__ import annotations

import argparse
import re
import sys
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# Projects built from this repository (never pinned: they are the thing being installed).
OWN = {"illumix", "illumix-client"}
BUILD_TOOLS = ("pip", "setuptools")


def canon(name: str) -> str:
    """PEP 503 normalised project name."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _project_requirements(extras: list[str]) -> list[str]:
    import tomllib

    proj = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(proj.get("dependencies", []))
    optional = proj.get("optional-dependencies", {})
    for e in extras:
        if e not in optional:
            sys.exit(f"pins: pyproject.toml has no extra {e!r} (has: {', '.join(optional)})")
        reqs += optional[e]
    return reqs


def freeze(extras: list[str], also: list[str] | None = None) -> dict[str, str]:
    from packaging.requirements import Requirement

    pins: dict[str, str] = {}
    missing: list[str] = []
    todo: list[tuple[str, frozenset[str]]] = []

    def push(req_text: str, active_extras: frozenset[str]) -> None:
        req = Requirement(req_text)
        if req.marker is not None:
            envs = [{"extra": e} for e in active_extras] or [{"extra": ""}]
            if not any(req.marker.evaluate(env) for env in envs):
                return
        todo.append((req.name, frozenset(req.extras)))

    for r in _project_requirements(extras) + list(also or []):
        push(r, frozenset())
    seen: set[tuple[str, frozenset[str]]] = set()
    while todo:
        name, want = todo.pop()
        key = (canon(name), want)
        if key in seen or canon(name) in OWN:
            continue
        seen.add(key)
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            missing.append(name)
            continue
        pins[canon(dist.metadata["Name"])] = dist.version
        for r in dist.requires or []:
            push(r, want)
    if missing:
        sys.exit("pins: not installed here, so cannot be pinned: " + ", ".join(sorted(set(missing)))
                 + " (install the extras first)")
    for tool in BUILD_TOOLS:
        pins[tool] = metadata.version(tool)
    return dict(sorted(pins.items()))


def read_constraints(path: Path) -> dict[str, str]:
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = re.fullmatch(r"([A-Za-z0-9_.\-]+)==([^\s;]+)", line)
        if not m:
            sys.exit(f"pins: {path}: not a 'name==version' pin: {line!r}")
        pins[canon(m.group(1))] = m.group(2)
    return pins


def check(path: Path) -> int:
    pins = read_constraints(path)
    bad = []
    for dist in metadata.distributions():
        name = canon(dist.metadata["Name"])
        if name in OWN:
            continue
        if name not in pins:
            bad.append(f"{name}=={dist.version} is installed but not pinned in {path.name}")
        elif pins[name] != dist.version:
            bad.append(f"{name}=={dist.version} is installed but {path.name} pins {pins[name]}")
    for line in bad:
        print(f"pins: {line}", file=sys.stderr)
    if bad:
        print("pins: regenerate with `python docker/pins.py freeze` in a tested environment", file=sys.stderr)
        return 1
    print(f"pins: every installed distribution matches {path.name}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("freeze", help="write constraints from this environment")
    f.add_argument("--extras", default="render,ray", help="extras of pyproject.toml to include")
    f.add_argument("--also", default="", help="more requirements to pin, comma-separated (e.g. s3fs)")
    f.add_argument("--out", type=Path, default=ROOT / "docker" / "constraints.txt")
    c = sub.add_parser("check", help="fail if an installed distribution is not pinned")
    c.add_argument("constraints", type=Path)
    a = ap.parse_args()
    if a.cmd == "check":
        return check(a.constraints)
    extras = [e.strip() for e in a.extras.split(",") if e.strip()]
    also = [r.strip() for r in a.also.split(",") if r.strip()]
    pins = freeze(extras, also)
    py = ".".join(map(str, sys.version_info[:3]))
    cmd = f"python docker/pins.py freeze --extras {','.join(extras)}" + (f" --also {','.join(also)}" if also else "")
    header = (f"# Generated by `{cmd}` (Python {py}).\n"
              "# pip freeze pins of illumix's dependency closure (base + those extras) in a tested\n"
              "# environment; the images install with `pip install -c` this file and fail on anything\n"
              "# unpinned (`python docker/pins.py check`). Regenerate after changing dependencies.\n")
    a.out.write_text(header + "".join(f"{n}=={v}\n" for n, v in pins.items()))
    print(f"pins: wrote {len(pins)} pins to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
