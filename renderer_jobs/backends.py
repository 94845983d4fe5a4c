"""Renderer backends behind one protocol.

A backend turns a scene's view into transport cubes (and AOVs) and writes them into the store
through :mod:`renderer_jobs.jobs`' store adapters. The planner (:func:`renderer_jobs.jobs.plan`) and
the dispatcher (:func:`renderer_jobs.execute.execute`) know only this protocol; the registry
(:data:`renderer_jobs.modes.BACKENDS`, case-insensitive, with aliases) names each backend's module,
imported on first use: only :mod:`renderer_jobs.mitsuba.backend` and the ``mitsuba_*`` modules it
reaches import ``mitsuba``; only the Blender worker (:mod:`renderer_jobs.cycles.worker`, run by
Blender's own Python) imports ``bpy``.

Adding a renderer: a module with a class implementing :class:`Backend` and ``BACKEND = TheClass()``,
and one :class:`renderer_jobs.modes.BackendEntry` in :data:`renderer_jobs.modes.BACKENDS`. A backend
that renders one job at a time subclasses :class:`JobBackend` and implements ``run_job``: the
dispatcher runs its jobs on this machine's process pool or as Ray tasks; one that batches (Cycles
renders a view's groups in one Blender run) implements ``run`` instead.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from illumix.renderer_jobs.modes import BACKENDS

if TYPE_CHECKING:
    from illumix.renderer_jobs.jobs import Job, Plan, ProgressFn
    from illumix.renderer_jobs.mitsuba.render import CubeResult
    from illumix.renderer_jobs.render_settings import RenderSettings
    from illumix.scene.model import Scene


class RenderError(RuntimeError):
    """The renderer could not run (a package or program missing, a renderer failure)."""


class Backend(Protocol):
    """What the planner and the dispatcher need of a renderer."""

    name: str
    #: the executors it runs on ("local": this machine; "ray": a cluster); others are refused
    executors: tuple[str, ...]

    def require(self) -> None:
        """Raise a one-line error when this machine cannot render with it (a package or a program
        missing), before anything is planned or written."""

    def render_cube(self, scene: Scene, view: str, group: str, settings: RenderSettings) -> CubeResult:
        """One group's transport cube of ``view``, not stored (validation, benchmarks)."""

    # ... and either ``run_job`` (:class:`JobBackend`: the executors run the jobs one by one) or:
    def run(self, plan: Plan, store_path: str, settings_dict: dict, *, executor: str, workers: int,
            address: str | None, on_done: ProgressFn, ray_init: dict | None, overwrite: bool,
            on_pass: Callable[[int, int, str], None] | None, keep_going: bool) -> list[dict]:
        """Render every job of ``plan`` into the store (view jobs first); per-job summaries. For a
        backend that batches jobs itself."""


class JobBackend:
    """A backend that renders one job at a time (:meth:`run_job`), on this machine's process pool
    or as Ray tasks."""

    name = ""
    executors = ("local", "ray")

    def require(self) -> None:
        raise NotImplementedError

    def render_cube(self, scene: Scene, view: str, group: str, settings: RenderSettings) -> CubeResult:
        raise NotImplementedError

    def run_job(self, payload: tuple[dict, str | None], job: Job, store_path: str, settings_dict: dict,
                threads: int | None = None, overwrite: bool = False) -> dict:
        """Render one job (a view's AOVs, or one group's cube) and write it into the store; the
        executors call it through :func:`renderer_jobs.jobs.run_job`, in worker processes or Ray tasks."""
        raise NotImplementedError


def get_backend(name: str) -> Backend:
    """The backend registered as ``name`` (any accepted spelling); :class:`retarget.errors.UnknownName`
    with the valid choices otherwise."""
    entry = BACKENDS[BACKENDS.canonical(name)]
    return importlib.import_module(entry.module).BACKEND


__all__ = ["Backend", "JobBackend", "RenderError", "get_backend"]
