"""The one progress bar of the long commands (render, dataset, scenes): description, bar, done/total,
elapsed time and the last finished item (a task's ``last`` field). Rich is imported on use, so
``--help`` stays cheap."""

from __future__ import annotations


def progress_bar(console, *, disable: bool = False, transient: bool = False):
    """A ``rich.progress.Progress`` on ``console`` (stderr); add tasks with a ``last=""`` field."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    TextColumn("{task.fields[last]}"), console=console, disable=disable, transient=transient)
