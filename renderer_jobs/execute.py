"""Run a render plan's jobs with its backend (:mod:`renderer_jobs.backends`) on an executor: this
machine's process pool or a Ray cluster (the Cycles backend: Blender on this machine). Above
:mod:`renderer_jobs.jobs` and the executors, which import the jobs module and never this one."""

from __future__ import annotations

from collections.abc import Callable

from illumix.renderer_jobs import jobs
from illumix.renderer_jobs.backends import get_backend
from illumix.renderer_jobs.modes import EXECUTORS
from illumix.scene.schema import SceneError


def execute(plan_: jobs.Plan, store_path: str, settings, *, executor: str = "local", workers: int = 1,
            address: str | None = None, on_done: jobs.ProgressFn | None = None,
            ray_init: dict | None = None, overwrite: bool = False,
            on_pass: Callable[[int, int, str], None] | None = None, keep_going: bool = False) -> list[dict]:
    """Run every job of ``plan_`` (view jobs first, then cubes) and return per-job summaries.
    ``on_pass(done, total, label)``: the Cycles backend's progress through a view's passes.
    ``keep_going`` (local executor): a failed job is reported to ``on_done`` (with its exception)
    and the others go on (the cubes of a failed view are reported failed without running);
    default: the first failure stops the run with :class:`JobError`. The Ray and Cycles executors
    always stop at the first failure."""
    if executor not in EXECUTORS:
        raise SceneError(str(EXECUTORS.unknown(executor)))
    executor = EXECUTORS.canonical(executor)
    settings_dict = settings.to_dict() if hasattr(settings, "to_dict") else dict(settings)
    cb = on_done or (lambda job, r, exc: None)
    if not plan_.jobs:
        return []
    backend = get_backend(settings_dict.get("backend", "mitsuba"))
    if executor not in backend.executors:  # refused before anything is deleted or written
        raise SceneError(f"the {backend.name} backend runs on the executors {', '.join(backend.executors)}"
                         f"{' (' + backend.executor_note + ')' if getattr(backend, 'executor_note', '') else ''}, "
                         f"not {executor}: leave out --executor {executor}")
    if plan_.replace_views:
        st = jobs._open_store(store_path, mode="a")
        for scene, view in plan_.replace_views:
            st.delete(scene, view)
    if hasattr(backend, "run"):  # a backend that batches its jobs itself
        return backend.run(plan_, store_path, settings_dict, executor=executor, workers=workers, address=address,
                           on_done=cb, ray_init=ray_init, overwrite=overwrite, on_pass=on_pass, keep_going=keep_going)
    if executor == "ray":  # one job at a time (backend.run_job, through jobs.run_job)
        from illumix.renderer_jobs.ray_executor import run_ray

        return run_ray(plan_, store_path, settings_dict, address, cb, ray_init, overwrite)
    from illumix.renderer_jobs.local_executor import run_local

    return run_local(plan_, store_path, settings_dict, workers, cb, overwrite, keep_going)


__all__ = ["execute"]
