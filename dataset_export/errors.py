"""The export's errors: a problem with what was asked (:class:`ExportError`; the CLI prints it as one line,
exit 2), and a write the disk refused (:class:`ExportWriteError`)."""

from __future__ import annotations

from illumix.retarget.errors import SpectralError


class ExportError(SpectralError):
    """What is wrong, where, and how to fix it (a :class:`SpectralError`, so ``illumix`` reports it as one line)."""


def require(module: str, what: str) -> None:
    """Raise :class:`ExportError` naming the install command when ``module`` (from the ``export``
    extra) cannot be imported; ``what`` says what needs it."""
    import importlib.util

    try:
        found = importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a parent package missing, or blocked
        found = False
    if not found:
        raise ExportError(f"{what} needs the Python package {module!r}, which is not installed; "
                          "install the export extra: pip install -e '.[export]' (or bash scripts/install.sh --test)")


class ExportWriteError(OSError):
    """A file of the export the disk refused (full, read-only, failing): ``errno`` (``None`` when the
    writer gave none, e.g. numpy's "57600 requested and 38880 written"), ``strerror`` and ``filename``,
    the file that was not written. Nothing half-written is left under its name; the command line
    words it as one line (:func:`illumix.errors.write_failure`) and a rerun resumes."""

    @classmethod
    def of(cls, exc: BaseException, filename) -> ExportWriteError:
        n = getattr(exc, "errno", None)
        text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        return cls(n if isinstance(n, int) else None, text, str(filename))


def system_error(exc: BaseException) -> OSError | None:
    """The ``OSError`` a library's non-``OSError`` exception stands for, when its message names an
    operating-system error (``No space left on device``, ``Read-only file system`` …); else ``None``.
    OpenEXR, for one, raises ``RuntimeError('Failed to write pixel data to image file "…". No space
    left on device.')``."""
    import errno
    import os

    text = str(exc)
    for n in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EIO):
        if os.strerror(n) in text:
            return OSError(n, os.strerror(n))
    return None
