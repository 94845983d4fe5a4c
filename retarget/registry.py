"""Method families by name, the colour-science way (``method="Gray World"``).

A :class:`MethodRegistry` maps a family's canonical names to their implementations (a function, a
parameter set, a plain flag). Look-ups are case-insensitive and ignore spaces, hyphens and
underscores, as colour-science's ``CanonicalMapping`` does (``"white preserving"``,
``"White-Preserving"`` and ``"whitepreserving"`` are one name), and a family may declare aliases
(``"auto"`` for the ``"constant"`` exposure method). An unknown name raises
:class:`retarget.errors.UnknownName` listing the valid names and the close matches.

Pure Python on purpose: the command line builds its option choices from these registries while it
starts, so importing this module must stay cheap (no colour-science, no numpy).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from typing import Generic, TypeVar

from illumix.retarget.errors import UnknownName, close_matches

T = TypeVar("T")
_FOLD = re.compile(r"[\s_\-]+")


def fold(name: str) -> str:
    """The comparison key of a name: lower case without spaces, hyphens or underscores."""
    return _FOLD.sub("", str(name)).lower()


class MethodRegistry(Mapping[str, T], Generic[T]):
    """Canonical name → implementation, with case-insensitive look-up and aliases.

    ``kind`` names the family in error messages (``"CCM method"``). Iteration, ``len`` and
    :attr:`names` give the canonical names in declaration order; ``in`` and ``[]`` accept any
    spelling or alias.
    """

    def __init__(self, kind: str, entries: Mapping[str, T], aliases: Mapping[str, str] | None = None) -> None:
        self.kind = kind
        self._entries = dict(entries)
        self._keys: dict[str, str] = {}
        for name in self._entries:
            self._add_key(name, name)
        for alias, target in (aliases or {}).items():
            if target not in self._entries:
                raise ValueError(f"{kind}: alias {alias!r} points to unknown name {target!r}")
            self._add_key(alias, target)
        self.aliases = dict(aliases or {})

    def _add_key(self, spelling: str, canonical: str) -> None:
        key = fold(spelling)
        if self._keys.get(key, canonical) != canonical:
            raise ValueError(f"{self.kind}: {spelling!r} collides with {self._keys[key]!r}")
        self._keys[key] = canonical

    @property
    def names(self) -> list[str]:
        """Canonical names, in declaration order."""
        return list(self._entries)

    def choices(self) -> list[str]:
        """Every accepted spelling a user may type: canonical names, then aliases (for CLI choices)."""
        return self.names + [a for a in self.aliases if a not in self._entries]

    def canonical(self, name: str) -> str:
        """The canonical name for any accepted spelling; :class:`UnknownName` otherwise."""
        found = self._keys.get(fold(name)) if isinstance(name, str) else None
        if found is None:
            raise self.unknown(name)
        return found

    def unknown(self, name: object) -> UnknownName:
        """The error for a name not in the family: the valid names and the close matches."""
        spellings = self.choices()
        close = close_matches(str(name), spellings, cutoff=0.6, key=fold)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        return UnknownName(f"unknown {self.kind} {name!r}{hint} (valid: {', '.join(self.choices())})")

    def __getitem__(self, name: str) -> T:
        return self._entries[self.canonical(name)]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and fold(name) in self._keys

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"MethodRegistry({self.kind!r}, {self.names})"
