"""The export's one error type: a problem with what was asked (the CLI prints it as one line, exit 2)."""

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
