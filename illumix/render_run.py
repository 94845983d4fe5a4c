"""Running a render plan from the command line, shared by ``illumix render`` and ``illumix dataset``:
the plan's conflicts as one line, and the jobs with a progress bar (the Cycles backend's passes as a
second bar), every failure reported as one line (exit 2 through :class:`UserError`)."""

from __future__ import annotations

from rich.console import Console

from illumix.errors import UserError


def refuse_conflicts(p, overwrite: bool, hint: str) -> None:
    """One line for a plan whose store holds some of its cubes rendered otherwise (unless ``overwrite``)."""
    if p.conflicts and not overwrite:
        more = f" (and {len(p.conflicts) - 1} more)" if len(p.conflicts) > 1 else ""
        raise UserError(f"{p.conflicts[0]}{more}; {hint}")


def run_jobs(console: Console, p, store: str, settings, *, executor: str, workers: int, address: str | None,
             overwrite: bool, quiet: bool, keep_going: bool = False) -> tuple[list[dict], list[dict]]:
    """Execute plan ``p``: ``(summaries of the jobs done, [{"job", "error"}] of those that failed)``.
    ``keep_going``: a failed job is listed (and printed) and the others go on; else the first
    failure stops the run with one line saying the finished jobs are kept."""
    from illumix.progress import progress_bar
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.scene.spectra import SceneError

    done: list[dict] = []
    failed: list[dict] = []
    with progress_bar(console, disable=quiet) as prog:
        task = prog.add_task("rendering", total=len(p.jobs), last="")
        passes = None

        def on_pass(n: int, total: int, label: str) -> None:  # the Cycles backend's passes
            nonlocal passes
            if passes is None:
                passes = prog.add_task("cycles passes", total=total, last="")
            if n == 0:
                prog.reset(passes, total=total, last="")
            prog.update(passes, completed=n, last=label)

        def on_done(job, result, exc) -> None:
            if exc is None:
                done.append(result)
                prog.update(task, advance=1, last=f"{job.label} {result['seconds']:.1f}s")
                return
            prog.update(task, advance=int(keep_going), last=f"[red]{job.label} failed")
            if keep_going:
                line = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                failed.append({"job": job.label, "error": line})
                prog.console.print(f"[red]failed[/red] {job.label}: {line}", markup=True, highlight=False)

        try:
            execute(p, store, settings, executor=executor, workers=workers, address=address, on_done=on_done,
                    overwrite=overwrite, on_pass=on_pass, keep_going=keep_going)
        except SceneError as exc:
            raise UserError(str(exc)) from None
        except jobs.JobError as exc:  # (Ray stops at its first failure even when keeping going)
            raise UserError(f"render failed: {str(exc).splitlines()[0]} ({len(done)} job(s) finished "
                            "and are kept; run again to resume)") from None
    return done, failed
