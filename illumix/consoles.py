"""The CLI's rich consoles. On a terminal they are as wide as the terminal; written to a pipe or a
file (logs, CI, ``| grep``, ``| less``) rich would lay everything out for 80 columns and cut table
cells to ``demo-…``, so there they are :data:`PIPE_WIDTH` wide instead: tables take the width their
cells need and lines are not wrapped. ``COLUMNS`` (or an explicit ``width``) still decides where set.
A rule (``console.rule``) stays 80 wide in a pipe."""

from __future__ import annotations

from rich.console import Console, ConsoleDimensions

PIPE_WIDTH = 1000  # wide enough for any table row the CLI prints; rich only pads to what cells need
RULE_WIDTH = 80


class PipeAwareConsole(Console):
    """:class:`rich.console.Console` whose width off a terminal is :data:`PIPE_WIDTH` (module docstring).
    The test is made on each use, so a console created at import follows whatever stream it writes to
    (a pytest capture, a redirected ``sys.stdout``)."""

    def _piped(self) -> bool:
        columns = self._environ.get("COLUMNS")
        return (self._width is None and not self.is_terminal and not self.is_jupyter
                and not (columns is not None and columns.isdigit()))

    @property
    def size(self) -> ConsoleDimensions:
        size = super().size
        return ConsoleDimensions(PIPE_WIDTH, size.height) if self._piped() else size

    @size.setter
    def size(self, new_size: tuple[int, int]) -> None:
        Console.size.fset(self, new_size)

    def rule(self, *args, **kwargs) -> None:
        if not self._piped():
            return super().rule(*args, **kwargs)
        from rich.rule import Rule

        self.print(Rule(*args, **kwargs), width=RULE_WIDTH)


def make_console(*, stderr: bool = False) -> Console:
    """The console of a command: stdout (results) or ``stderr=True`` (messages, progress)."""
    return PipeAwareConsole(stderr=stderr)
