"""The one exception type the physics core raises for bad input."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class SpectralError(ValueError):
    """Bad spectral input: what is wrong, where, and how to fix it, in one line."""


class UnknownName(SpectralError):
    """A library name (illuminant, sensor, reflectance set) that does not exist."""


def unknown_name(kind: str, name: str, known: Iterable[str]) -> UnknownName:
    """A clear error for an unknown library name, with close-match suggestions."""
    known = list(known)
    lowered = {k.lower(): k for k in known}
    close = difflib.get_close_matches(name.lower(), list(lowered), n=3, cutoff=0.5)
    hint = f"; did you mean {', '.join(repr(lowered[c]) for c in close)}?" if close else ""
    listing = f" (list them with `illumix {kind}s list`)" if kind in ("sensor", "illuminant") else ""
    return UnknownName(f"unknown {kind} {name!r}{hint}{listing}")
