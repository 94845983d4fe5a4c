"""Run a render plan's jobs on an executor: this process's pool, a Ray cluster, or (for the Cycles
backend) Blender on this machine. Above :mod:`renderer_jobs.jobs` and the executors, which import
the jobs module and never this one."""

from __future__ import annotations

from collections.abc import Callable

from renderer_jobs import jobs
from renderer_jobs.modes import EXECUTORS
from renderer_jobs.scene_schema import SceneError


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
    if plan_.replace_views:
        st = jobs._open_store(store_path, mode="a")
        for scene, view in plan_.replace_views:
            st.delete(scene, view)
    if settings_dict.get("backend", "mitsuba") == "cycles":
        if executor != "local":
            raise SceneError("the cycles backend runs on this machine (Blender uses every core): "
                             "leave out --executor ray")
        from renderer_jobs.cycles_jobs import run_cycles

        return run_cycles(plan_, store_path, settings_dict, cb, overwrite, on_pass)
    if executor == "ray":
        from renderer_jobs.ray_executor import run_ray

        return run_ray(plan_, store_path, settings_dict, address, cb, ray_init, overwrite)
    from renderer_jobs.local_executor import run_local

    return run_local(plan_, store_path, settings_dict, workers, cb, overwrite, keep_going)


__all__ = ["execute"]
