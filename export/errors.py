"""The export's one error type: a problem with what was asked (the CLI prints it as one line, exit 2)."""

from retarget.errors import SpectralError


class ExportError(SpectralError):
    """What is wrong, where, and how to fix it (a :class:`SpectralError`, so ``illumix`` reports it as one line)."""
