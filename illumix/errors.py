"""Errors the CLI reports as one line (exit 2), and the wording of a write the storage refused.

A full disk, a read-only or failing one, or a folder without permission is not a bug: every writer
(``render``, ``dataset``, ``export``, ``evaluate --out``) says in one line what it could not write,
why, and how to go on (:func:`write_failure`); what was complete is kept and a rerun resumes.
Standard library only: ``illumix --help`` imports this module.
"""

from __future__ import annotations

import errno
import os


class UserError(Exception):
    """A problem with what the user asked for; the message says what, where and how to fix it."""


#: the errors of the storage rather than of the input, each with what to do about it
#: (``{elsewhere}``: the command's other place to write, e.g. "choose another --store")
STORAGE_ERRNOS: dict[int, str] = {
    errno.ENOSPC: "free space on that disk or {elsewhere}",
    errno.EDQUOT: "free space within your disk quota or {elsewhere}",
    errno.EFBIG: "{elsewhere} on a file system that holds larger files",
    errno.EROFS: "{elsewhere} on a writable disk",
    errno.EACCES: "make it writable for you or {elsewhere}",
    errno.EPERM: "make it writable for you or {elsewhere}",
    errno.EIO: "check the disk or mount (dmesg) or {elsewhere}",
}


def storage_errno(exc: BaseException | None) -> int | None:
    """The :data:`STORAGE_ERRNOS` number ``exc`` carries (an ``OSError``, or any error with an
    ``errno`` such as the store's ``StoreWriteError``), or that an error it was raised from carries;
    ``None`` when it is not a storage error."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        n = getattr(exc, "errno", None)
        if isinstance(n, int) and n in STORAGE_ERRNOS:
            return n
        exc = exc.__cause__ or exc.__context__
    return None


def write_failure(target: object, exc: BaseException, *, elsewhere: str,
                  rerun: str = "run the same command again: it resumes") -> str:
    """One line: ``could not write <target>: <why>; <fix>, then <rerun>``. ``exc`` is what the write
    raised (an ``OSError`` without a number, e.g. numpy's "57600 requested and 38880 written",
    reads as a full disk when the disk of ``target`` has under 1 MiB free, else as a possibly full or
    failing one); ``elsewhere`` the command's other place to write."""
    n = storage_errno(exc)
    if n is None and _disk_full(target):  # numpy's "… requested and … written" carries no errno
        n = errno.ENOSPC
    if n is not None:
        why = os.strerror(n)
        fix = STORAGE_ERRNOS[n].format(elsewhere=elsewhere)
    else:
        text = str(getattr(exc, "strerror", None) or exc).strip()
        why = text.splitlines()[0] if text else type(exc).__name__
        fix = f"check that the disk has free space and works, or {elsewhere}"
    return f"could not write {target}: {why}; {fix}, then {rerun}"


def _disk_full(target: object, free_below: int = 1 << 20) -> bool:
    """Whether ``target`` names a file on a disk with less than ``free_below`` bytes free."""
    import shutil
    from pathlib import Path

    if not isinstance(target, (str, os.PathLike)):
        return False
    p = Path(target)
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return shutil.disk_usage(p).free < free_below
    except OSError:
        return False
