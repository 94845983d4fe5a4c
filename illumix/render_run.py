"""Running a render plan from the command line, shared by ``illumix render`` and ``illumix dataset``:
the plan's conflicts as one line, and the jobs with their progress (:class:`JobReport`: a bar on a
terminal, plain lines with an ETA and a heartbeat in a log), every failure reported as one line
(exit 2 through :class:`UserError`).

A write the store's disk refuses (full, read-only, failing: :func:`illumix.errors.storage_errno`)
stops the run at once, even one that keeps going past failed jobs: every further job would fail
the same way. The store's writers stage each node and discard it when a write fails, so only
complete cubes stay, and the next run renders the rest."""

from __future__ import annotations

from rich.console import Console

from illumix.errors import UserError, storage_errno, write_failure


#: seconds of long work between two heartbeat lines in a log (:class:`JobReport`)
HEARTBEAT_S = 10.0


def refuse_conflicts(p, overwrite: bool, hint: str) -> None:
    """One line for a plan whose store holds some of its cubes rendered otherwise (unless ``overwrite``)."""
    if p.conflicts and not overwrite:
        more = f" (and {len(p.conflicts) - 1} more)" if len(p.conflicts) > 1 else ""
        raise UserError(f"{p.conflicts[0]}{more}; {hint}")


def run_jobs(console: Console, p, store: str, settings, *, executor: str, workers: int, address: str | None,
             overwrite: bool, quiet: bool, keep_going: bool = False) -> tuple[list[dict], list[dict]]:
    """Execute plan ``p``: ``(summaries of the jobs done, [{"job", "error"}] of those that failed)``.
    ``keep_going``: a failed job is listed (and printed) and the others go on; else the first
    failure stops the run with one line saying the finished jobs are kept. Progress: a bar on a
    terminal, plain lines anywhere else (:class:`JobReport`), none when ``quiet``."""
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.scene.spectra import SceneError

    done: list[dict] = []
    failed: list[dict] = []
    with JobReport(console, p, settings, executor=executor, workers=workers, quiet=quiet) as report:

        def on_done(job, result, exc) -> None:
            if exc is None:
                done.append(result)
                report.done(job, result)
                return
            if storage_errno(exc) is not None:  # no later job could be written either
                raise storage_failure(store, exc, len(done), job.label)
            line = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
            if keep_going:
                failed.append({"job": job.label, "error": line})
            report.failed(job, line, keep_going)

        try:
            execute(p, store, settings, executor=executor, workers=workers, address=address, on_done=on_done,
                    overwrite=overwrite, on_pass=report.on_pass, keep_going=keep_going)
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


class JobReport:
    """The progress of :func:`run_jobs`: on a terminal the rich bar (the Cycles backend's passes as a
    second bar); anywhere else (a log, CI, ``2> log``) plain lines on stderr, one per finished job
    with the time, the mean per job and an ETA weighted by the cost model, and a heartbeat every
    ``interval`` seconds of long work (:class:`illumix.progress.ProgressLines`); nothing when ``quiet``."""

    def __init__(self, console: Console, p, settings, *, executor: str, workers: int, quiet: bool,
                 interval: float | None = None) -> None:
        from illumix.progress import ProgressLines, progress_bar, stream_writer

        interval = HEARTBEAT_S if interval is None else interval
        self.console, self.bar, self.lines, self.passes = console, None, None, None
        if quiet or console.is_terminal:
            self.bar = progress_bar(console, disable=quiet)
            self.task = self.bar.add_task("rendering", total=len(p.jobs), last="")
            return
        mitsuba = getattr(settings, "backend", "mitsuba") == "mitsuba"
        parallel = (max(1, workers) if executor == "local" else None) if mitsuba else None
        order = [(j.label, 0 if j.group is None else 1) for j in p.jobs]
        self.lines = ProgressLines(stream_writer(console), order, parallel=parallel, interval=interval,
                                   weights=_weights(p, settings) if mitsuba else None)
        n_views, where = len(p.view_jobs), f"{workers} worker(s)" if executor == "local" else "Ray"
        stream_writer(console)(f"rendering {len(p.jobs)} job(s) ({n_views} view(s), {len(p.jobs) - n_views} "
                               f"cube(s)) on {where}: a line per finished job, another every {interval:g} s")

    def __enter__(self) -> JobReport:
        (self.bar or self.lines).__enter__()
        return self

    def __exit__(self, *exc) -> None:
        (self.bar or self.lines).__exit__(*exc)

    def done(self, job, result: dict) -> None:
        if self.lines is None:
            self.bar.update(self.task, advance=1, last=f"{job.label} {result['seconds']:.1f}s")
            return
        note = ("skipped: " + str(result["skipped"])) if result.get("skipped") else (
            "lights nothing in its view: recorded as empty" if result.get("empty") else "")
        self.lines.job_done(job.label, result.get("seconds"), note)

    def failed(self, job, line: str, keep_going: bool) -> None:
        if self.lines is not None:
            if keep_going:  # else the run stops with one line of its own
                self.lines.job_failed(job.label, line)
            return
        self.bar.update(self.task, advance=int(keep_going), last=f"[red]{job.label} failed")
        if keep_going:
            self.bar.console.print(f"[red]failed[/red] {job.label}: {line}", markup=True, highlight=False)

    def on_pass(self, n: int, total: int, label: str) -> None:
        """The Cycles backend's passes: a second bar, or named by the next heartbeat line."""
        if self.lines is not None:
            self.lines.pass_done(f"pass {n}/{total} {label}".rstrip())
            return
        if self.passes is None:
            self.passes = self.bar.add_task("cycles passes", total=total, last="")
        if n == 0:
            self.bar.reset(self.passes, total=total, last="")
        self.bar.update(self.passes, completed=n, last=label)


def plan_estimate(p, settings, workers: int, executor: str):
    """The cost model's :class:`~renderer_jobs.cost_model.Estimate` of plan ``p`` (None where it cannot say)."""
    try:
        from illumix.renderer_jobs.cost_model import estimate

        return estimate(p, settings, workers, executor)
    except Exception:  # an estimate is never worth a failed command
        return None


def print_estimate(console: Console, est, summary: dict, show: bool = True) -> None:
    """The estimate's keys into the JSON ``summary`` (``estimate_cpu_s``, ``estimate_wall_s``, …) and,
    with ``show``, its line on ``console`` (unwrapped)."""
    summary.update(est.to_json() if est is not None else {"estimate_cpu_s": None, "estimate_wall_s": None})
    if show:
        console.print(est.line() if est is not None else "estimate: none for this backend (the cost table was "
                      "measured with Mitsuba)", highlight=False, soft_wrap=True)


def _weights(p, settings) -> dict[str, float] | None:
    """The cost model's CPU seconds per job: the ETA's weights (None where the model cannot say)."""
    try:
        from illumix.renderer_jobs.cost_model import weights

        return weights(p, settings)
    except Exception:  # a progress estimate is never worth a failed render
        return None


def storage_failure(store: str, exc: BaseException, n_done: int | None = None, label: str | None = None) -> UserError:
    """One line for a render stopped by a disk that refuses writes (module docstring): job ``label``
    (or the store itself) could not be written; ``n_done`` jobs finished before."""
    what = f"{label} into the store {store}" if label else f"the store {store}"
    rerun = "run the same command again: it resumes" if not n_done else (
        f"run the same command again: the {n_done} job(s) finished are kept and it renders the rest")
    return UserError(write_failure(what, exc, elsewhere="render into another --store", rerun=rerun))
