"""The one exception type the physics core raises for bad input."""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable, Iterable


class SpectralError(ValueError):
    """Bad spectral input: what is wrong, where, and how to fix it, in one line."""


class UnknownName(SpectralError):
    """A library name (illuminant, sensor, reflectance set) that does not exist."""


_WORDS = re.compile(r"[\s_\-()/.,:]+")


def close_matches(name: str, known: Iterable[str], n: int = 3, cutoff: float = 0.5,
                  key: Callable[[str], str] = str.lower) -> list[str]:
    """Up to ``n`` of ``known`` a mistyped ``name`` may have meant, compared by ``key`` (ignoring
    case): names it starts or is part of (``Nikon`` → ``Nikon 5100 (NPL)``, which a whole-name ratio
    misses), then whole names close by :func:`difflib.get_close_matches`, then names with a word close
    to it (``nikn``)."""
    keyed: dict[str, str] = {}
    for k in known:
        keyed.setdefault(key(str(k)), str(k))
    q = key(str(name)).strip()
    found: list[str] = []
    if len(q) >= 3:
        found += sorted((k for k in keyed if k.startswith(q)), key=len)
        found += sorted((k for k in keyed if q in k and not k.startswith(q)), key=len)
    found += difflib.get_close_matches(q, list(keyed), n=n, cutoff=cutoff)
    if len(q) >= 3 and len(found) < n:
        found += [k for k in keyed if difflib.get_close_matches(q, _WORDS.split(k), n=1, cutoff=0.8)]
    return [keyed[k] for k in dict.fromkeys(found)][:n]


def unknown_name(kind: str, name: str, known: Iterable[str]) -> UnknownName:
    """A clear error for an unknown library name, with close-match suggestions (:func:`close_matches`)."""
    close = close_matches(name, known)
    hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
    listing = f" (list them with `illumix {kind}s list`)" if kind in ("sensor", "illuminant") else ""
    return UnknownName(f"unknown {kind} {name!r}{hint}{listing}")
