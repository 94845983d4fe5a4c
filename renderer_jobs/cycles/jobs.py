"""Render jobs on the Cycles backend: one Blender run per view renders every pending light group
(Cycles light groups), so the planner's per-group cube jobs are gathered by view here; the store
writes (illumination cubes, denoised copies, empty groups) are :mod:`renderer_jobs.jobs`' own."""

from __future__ import annotations

import time
from collections.abc import Callable

from illumix.renderer_jobs.jobs import (
    Job,
    JobError,
    Plan,
    _open_store,
    _view_meta,
    store_result,
)
from illumix.renderer_jobs.local_executor import run_guarded
from illumix.scene.schema import SceneError


def run_cycles(plan_: Plan, store_path: str, settings_dict: dict, on_done, overwrite: bool = False,
               on_pass: Callable[[int, int, str], None] | None = None) -> list[dict]:
    """Execute ``plan_`` with Cycles in this process (sequentially: Blender uses every core)."""
    from illumix.renderer_jobs.cycles import render as cr
    from illumix.renderer_jobs.render_settings import RenderSettings

    settings = RenderSettings(**settings_dict)
    st = _open_store(store_path, mode="a")
    results: list[dict] = []

    def guarded(job: Job, fn) -> None:
        run_guarded(job, fn, on_done, results)

    for job in plan_.view_jobs:
        scene = plan_.scenes[job.scene]

        def view_job(job=job, scene=scene) -> dict:
            t0 = time.perf_counter()
            aovs = cr.render_aovs(scene, job.view, settings, progress=on_pass)
            st.write_view(scene.name, job.view, _view_meta(scene, job.view), aovs)
            return {"job": job.label, "seconds": time.perf_counter() - t0, "kind": "view"}
        guarded(job, view_job)
    by_view: dict[tuple[str, str], list[Job]] = {}
    for job in plan_.cube_jobs:
        by_view.setdefault((job.scene, job.view), []).append(job)
    for (scene_name, view), batch in by_view.items():
        scene = plan_.scenes[scene_name]
        t0 = time.perf_counter()
        try:
            cubes = cr.render_cubes(scene, view, settings, [j.group for j in batch], progress=on_pass,
                                    warn=_warn)
        except SceneError:
            raise
        except Exception as exc:
            on_done(batch[0], None, exc)
            raise JobError(f"{batch[0].label}: {type(exc).__name__}: {exc}") from exc
        seconds = (time.perf_counter() - t0) / len(batch)
        for job in batch:
            guarded(job, lambda job=job: {
                "job": job.label, "seconds": seconds, "kind": "cube",
                "empty": store_result(st, scene, job, cubes[job.group], settings, overwrite,
                                      {"view_batch": [j.group for j in batch]})})
    return results


def _warn(msg: str) -> None:
    import warnings

    warnings.warn(msg, UserWarning, stacklevel=2)
