"""Running a render plan from the command line, shared by ``illumix render`` and ``illumix dataset``:
the plan's conflicts as one line, and the jobs with a progress bar (the Cycles backend's passes as a
second bar), every failure reported as one line (exit 2 through :class:`UserError`).

A write the store's disk refuses (full, read-only, failing: :func:`illumix.errors.storage_errno`)
stops the run at once, even one that keeps going past failed jobs: every further job would fail
the same way. The store's writers stage each node and discard it when a write fails, so only
complete cubes stay, and the next run renders the rest."""

from __future__ import annotations

from rich.console import Console

from illumix.errors import UserError, storage_errno, write_failure


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
            if storage_errno(exc) is not None:  # no later job could be written either
                raise storage_failure(store, exc, len(done), job.label)
            prog.update(task, advance=int(keep_going), last=f"[red]{job.label} failed")
            if keep_going:
                line = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                failed.append({"job": job.label, "error": line})
                prog.console.print(f"[red]failed[/red] {job.label}: {line}", markup=True, highlight=False)

        try:
            execute(p, store, settings, executor=executor, workers=workers, address=address, on_done=on_done,
                    overwrite=overwrite, on_pass=on_pass, keep_going=keep_going)
        except (SceneError, UserError) as exc:
            raise UserError(str(exc)) from None
        except Exception as exc:
            if storage_errno(exc) is not None:  # e.g. deleting a view for --overwrite, or an executor's own error
                raise storage_failure(store, exc, len(done)) from None
            if not isinstance(exc, jobs.JobError):
                raise
            # (Ray stops at its first failure even when keeping going)
            raise UserError(f"render failed: {str(exc).splitlines()[0]} ({len(done)} job(s) finished "
                            "and are kept; run again to resume)") from None
    return done, failed


def storage_failure(store: str, exc: BaseException, n_done: int | None = None, label: str | None = None) -> UserError:
    """One line for a render stopped by a disk that refuses writes (module docstring): job ``label``
    (or the store itself) could not be written; ``n_done`` jobs finished before."""
    what = f"{label} into the store {store}" if label else f"the store {store}"
    rerun = "run the same command again: it resumes" if not n_done else (
        f"run the same command again: the {n_done} job(s) finished are kept and it renders the rest")
    return UserError(write_failure(what, exc, elsewhere="render into another --store", rerun=rerun))
