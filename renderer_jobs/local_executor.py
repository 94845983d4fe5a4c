"""The local executor of :mod:`renderer_jobs.jobs`: jobs in this process (``workers == 1``) or in a
pool of ``workers`` spawned processes, each with a Dr.Jit thread pool of ``cpu_count // workers``;
view jobs first, then cubes. With ``keep_going`` a failed job is reported and the others go on (the
cubes of a failed view are reported failed without running); else the first failure stops the run.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from illumix.renderer_jobs import jobs  # jobs.run_job looked up at call time (tests replace it)
from illumix.renderer_jobs.jobs import Job, JobError, Plan, ProgressFn, _scene_payload
from illumix.scene.schema import SceneError


def run_guarded(job: Job, fn: Callable[[], dict], on_done: ProgressFn, results: list[dict],
                keep_going: bool = False) -> None:
    """Run one job in this process: its summary goes to ``results`` and ``on_done``; a failure is
    reported to ``on_done`` and raised as :class:`JobError` naming the job (a bad scene as itself),
    or, with ``keep_going``, only reported."""
    try:
        r = fn()
    except SceneError as exc:
        if keep_going:
            on_done(job, None, exc)
            return
        raise
    except Exception as exc:
        on_done(job, None, exc)
        if keep_going:
            return
        raise JobError(f"{job.label}: {type(exc).__name__}: {exc}") from exc
    results.append(r)
    on_done(job, r, None)


class _ViewFailed(RuntimeError):
    """A cube job not run because its view job failed (keep-going runs)."""


def _cube_jobs_left(phase: list[Job], failed_views: set[tuple[str, str]], on_done: ProgressFn) -> list[Job]:
    """The jobs of ``phase`` whose view did not fail; the others are reported failed, not run."""
    keep = []
    for job in phase:
        if job.group is not None and (job.scene, job.view) in failed_views:
            on_done(job, None, _ViewFailed(f"its view {job.scene}/{job.view} failed"))
        else:
            keep.append(job)
    return keep


def run_local(plan_: Plan, store_path: str, settings_dict: dict, workers: int,
               on_done: ProgressFn, overwrite: bool = False, keep_going: bool = False) -> list[dict]:
    payloads = {n: _scene_payload(s) for n, s in plan_.scenes.items()}
    results: list[dict] = []
    cpu = os.cpu_count() or 1
    threads = max(1, cpu // max(1, workers))
    phases = [plan_.view_jobs, plan_.cube_jobs]
    failed_views: set[tuple[str, str]] = set()
    if keep_going:
        user_done = on_done

        def on_done(job, r, exc):  # remember failed views: their cubes cannot be stored
            if exc is not None and job.group is None:
                failed_views.add((job.scene, job.view))
            user_done(job, r, exc)
    if workers <= 1:
        for phase in phases:
            for job in _cube_jobs_left(phase, failed_views, on_done):
                run_guarded(job, lambda job=job: jobs.run_job(payloads[job.scene], job, store_path, settings_dict, None,
                                                         overwrite), on_done, results, keep_going)
        return results
    import multiprocessing as mp

    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
        for phase in phases:
            pending = {pool.submit(jobs.run_job, payloads[j.scene], j, store_path, settings_dict, threads, overwrite): j
                       for j in _cube_jobs_left(phase, failed_views, on_done)}
            try:
                while pending:
                    done, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in done:
                        job = pending.pop(fut)
                        exc = fut.exception()
                        if exc is not None:
                            on_done(job, None, exc)
                            if keep_going and not isinstance(exc, BrokenProcessPool):  # a dead pool runs nothing
                                continue
                            raise JobError(f"{job.label}: {exc}") from exc
                        results.append(fut.result())
                        on_done(job, fut.result(), None)
            except BaseException:
                for fut in pending:
                    fut.cancel()
                raise
    return results
