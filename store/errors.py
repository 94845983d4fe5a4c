"""Errors the cube store raises. Every message is one line: what is wrong, where, how to fix it."""

from __future__ import annotations

from collections.abc import Iterable

from illumix.retarget.errors import close_matches


class StoreError(ValueError):
    """A store problem: missing or corrupt data, a newer schema, a bad name, a refused write."""


class StoreWriteError(StoreError):
    """The storage refused a write (disk full, no permission, I/O error); nothing was written.

    ``errno`` is the operating system's error number (``errno.ENOSPC`` for a full disk), or ``None``.
    """

    def __init__(self, message: str, errno: int | None = None) -> None:
        super().__init__(message)
        self.errno = errno


class StoreKeyError(StoreError, KeyError):
    """An unknown scene, view, group, AOV or registry entry.

    ``kind`` is what was looked up (``"scene"``, ``"view"``, …), ``name`` the requested name and
    ``known`` the names that do exist, so a service can answer 404 with close matches.
    ``detail`` replaces the default message (e.g. for a cube that exists but is incomplete).
    """

    def __init__(self, kind: str, name: str, known: Iterable[str], where: str, detail: str | None = None) -> None:
        self.kind, self.name, self.known = kind, name, sorted(known)
        if detail:
            super().__init__(detail)
            return
        close = close_matches(name, self.known)
        hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        have = f" (known: {', '.join(self.known[:10])}{', …' if len(self.known) > 10 else ''})" \
            if self.known and not close else ""
        super().__init__(f"no {kind} {name!r} in {where}{hint}{have}")

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])
