"""Render jobs: every (scene, view, light group) cube not yet complete in the store, resumable.

A run is planned in the calling process (scenes validated, store consulted; nothing is written
until the whole plan is known to be valid), then executed by an executor:

- ``local`` (default): ``workers`` processes (``spawn``), or in-process when ``workers == 1``. Each
  process runs Dr.Jit's own thread pool, sized ``cpu_count // workers``.
- ``ray``: one Ray task per job on the cluster at ``address`` (``ray.init(address=...)``); the store
  location must be reachable from the workers (shared filesystem or an fsspec URL).

Jobs write straight into the store: first, per view, the view metadata and geometry AOVs; then one
cube per (view, group). With ``settings.skip_dark`` (the default) a cube job first probes whether
the group sends any light into the view (:mod:`renderer_jobs.mitsuba.light_probe`, ~1/16 of the cube's paths
at most); a dark group is recorded as empty (reads give zeros) without being rendered. A rendered
cube that comes out all zero is recorded as empty too. The store's writes are complete-or-invisible,
so an interrupted run leaves only whole cubes, and the next run renders what is missing (resume).

A cube already complete but rendered from a different scene description (another ``scene_hash``)
or at another resolution is a conflict: the run refuses to start unless ``overwrite`` is set.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path


from illumix.renderer_jobs.modes import EXECUTORS
from illumix.scene.load import scene_from_dict
from illumix.scene.model import Scene
from illumix.scene.schema import Dielectric, SceneError


class JobError(RuntimeError):
    """A render job failed (the message names the job)."""


@dataclass(frozen=True)
class Job:
    """One unit of work: ``group is None`` means "view metadata + AOVs" of ``view``."""

    scene: str
    view: str
    group: str | None

    @property
    def label(self) -> str:
        return f"{self.scene}/{self.view}/" + (self.group if self.group is not None else "[view+aovs]")


@dataclass
class Plan:
    scenes: dict[str, Scene]
    jobs: list[Job]
    skipped: list[Job] = field(default_factory=list)
    conflicts: list[str] = field(default_factory=list)
    #: stored views to delete before rendering (overwrite of a view whose camera/resolution changed)
    replace_views: list[tuple[str, str]] = field(default_factory=list)

    @property
    def cube_jobs(self) -> list[Job]:
        return [j for j in self.jobs if j.group is not None]

    @property
    def view_jobs(self) -> list[Job]:
        return [j for j in self.jobs if j.group is None]


def parse_resolution(text: str | None) -> tuple[int, int] | None:
    """``"WxH"`` → ``(W, H)``; None passes through. Raises :class:`SceneError` on anything else."""
    if text is None:
        return None
    parts = text.lower().replace("×", "x").split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise SceneError(f"resolution {text!r} is not WIDTHxHEIGHT (e.g. 320x240)") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise SceneError(f"resolution {text!r}: width and height must be 1..16384")
    return w, h


def apply_resolution(scene: Scene, resolution: tuple[int, int] | None) -> Scene:
    """The scene with every view's resolution replaced (None: unchanged)."""
    if resolution is None:
        return scene
    doc = scene.model_dump(mode="json")
    for v in doc["views"]:
        v["resolution"] = list(resolution)
    return scene_from_dict(doc, source=f"scene {scene.name!r}", base=scene._base, check=False)


# ---------------------------------------------------------------------------------------------
# Store adapter (the store package is the only place that knows the on-disk layout)


def _open_store(path: str, mode: str = "a"):
    from illumix.store import CubeStore

    return CubeStore.open(path, mode=mode)


def _view_meta(scene: Scene, view: str):
    from illumix.store import ViewMeta

    v = scene.view(view)
    return ViewMeta(width=v.width, height=v.height, origin=tuple(v.origin), target=tuple(v.target),
                    up=tuple(v.up), fov=v.fov, fov_axis="x", groups=scene.group_names,
                    scene_hash=scene.scene_hash, view_hash=scene.view_hash(view))


# Only "not there yet" is planned as missing; a store that cannot be read raises its StoreError
# (an unreadable view planned as empty was rendered again over the damage, or the damage hidden).


def _stored_view(st, scene: str, view: str):
    from illumix.store import StoreKeyError

    from illumix.store import StoreError

    try:
        healthy, damaged = st.view_health(scene)
        if view in damaged:  # views() leaves a damaged view out: here it must not read as "missing"
            raise StoreError(f"view {scene}/{view} is damaged: {damaged[view]}")
        if view not in healthy:
            return None
        return st.view_meta(scene, view)
    except StoreKeyError:  # a scene that does not exist yet has no views
        return None


def _stored_cube_meta(st, scene: str, view: str, group: str):
    from illumix.store import StoreKeyError

    try:
        return st.cube_meta(scene, view, group)
    except StoreKeyError:
        return None


def _scene_list(st) -> list[str]:
    return list(st.scenes())


def plan(scenes: Iterable[Scene], store_path: str | None, *, views: list[str] | None = None,
         groups: list[str] | None = None, overwrite: bool = False) -> Plan:
    """Jobs still to do for ``scenes`` against the store at ``store_path`` (None or missing: all).

    Reads the store only. ``views``/``groups`` restrict the plan (unknown names are errors).
    """
    scenes = list(scenes)
    by_name = {s.name: s for s in scenes}
    for s in scenes:
        for v in views or []:
            s.view(v)
        for g in groups or []:
            s.group(g)
    st = None
    if store_path is not None and _store_exists(store_path):
        st = _open_store(store_path, mode="r")
    out = Plan(scenes=by_name, jobs=[])
    for s in scenes:
        stored_scenes = _scene_list(st) if st is not None else []
        for v in s.views:
            if views and v.name not in views:
                continue
            vm = _stored_view(st, s.name, v.name) if (st is not None and s.name in stored_scenes) else None
            view_changed = False
            if vm is not None and (vm.width, vm.height) != (v.width, v.height):
                view_changed = True
                out.conflicts.append(f"{s.name}/{v.name}: the store holds it at {vm.width}x{vm.height}, "
                                     f"this run renders {v.width}x{v.height}")
            elif vm is not None and getattr(vm, "view_hash", None) not in (None, s.view_hash(v.name)):
                view_changed = True
                out.conflicts.append(f"{s.name}/{v.name}: the store holds this view rendered from a "
                                     "different scene description or camera")
            if view_changed and overwrite:
                # The store cannot change a view's resolution in place: the view (with every cube
                # of it) is deleted and re-rendered whole, whatever the group filter.
                out.replace_views.append((s.name, v.name))
            view_job = Job(s.name, v.name, None)
            if vm is None or overwrite:
                out.jobs.append(view_job)
            else:
                out.skipped.append(view_job)
            for g in s.group_names:
                if groups and g not in groups and (s.name, v.name) not in out.replace_views:
                    continue
                job = Job(s.name, v.name, g)
                done = vm is not None and st.is_complete(s.name, v.name, g)
                if done:
                    meta = _stored_cube_meta(st, s.name, v.name, g)
                    h = getattr(meta, "scene_hash", None) if meta is not None else None
                    if h and h != s.scene_hash:
                        out.conflicts.append(f"{job.label}: stored cube has scene_hash {h[:12]}…, the "
                                             f"description now hashes to {s.scene_hash[:12]}…")
                if done and not overwrite:
                    out.skipped.append(job)
                else:
                    out.jobs.append(job)
    return out


def _store_exists(path: str) -> bool:
    """A store is already at ``path`` (a missing path, an empty directory or an fsspec URL with
    nothing there yet is not one: the first job creates it)."""
    from illumix.store import CubeStore

    return CubeStore.exists(path)


# ---------------------------------------------------------------------------------------------
# Job execution (runs in worker processes / Ray tasks)


def _scene_payload(scene: Scene) -> tuple[dict, str | None]:
    return scene.model_dump(mode="json"), (str(scene._base) if scene._base is not None else None)


def _scene_from_payload(payload: tuple[dict, str | None]) -> Scene:
    doc, base = payload
    return scene_from_dict(doc, source="job scene", base=Path(base) if base else None, check=False)


def run_job(payload: tuple[dict, str | None], job: Job, store_path: str, settings_dict: dict,
            threads: int | None = None, overwrite: bool = False) -> dict:
    """Render one job with the settings' backend (:mod:`renderer_jobs.backends`) and write it into the
    store: the executors' task. Returns a small summary dict."""
    from illumix.renderer_jobs.backends import get_backend
    from illumix.store import StoreError

    if not overwrite and job.group is not None and _already_complete(payload, job, store_path):
        # a retried task (its first attempt's machine was lost after the cube was published), or a
        # rerun racing another: the cube is in the store once, never rendered into it a second time
        return {"job": job.label, "kind": "cube", "skipped": "already complete", "seconds": 0.0, "cpu_s": 0.0}
    backend = get_backend(settings_dict.get("backend", "mitsuba"))
    try:
        return backend.run_job(payload, job, store_path, settings_dict, threads, overwrite)
    except StoreError as exc:
        if overwrite or job.group is None or "already exists" not in str(exc):
            raise
        return {"job": job.label, "kind": "cube", "skipped": "written meanwhile by another task", "seconds": 0.0,
                "cpu_s": 0.0}


def _already_complete(payload, job: Job, store_path: str) -> bool:
    name = _scene_from_payload(payload).name
    return _open_store(store_path, mode="r").is_complete(name, job.view, job.group)


def cube_meta(scene: Scene, job: Job, settings, emission, emission_name: str, renderer: dict, stats: dict):
    """The store's :class:`store.schema.CubeMeta` of one rendered (or skipped) cube."""
    from illumix.store.schema import CubeMeta

    return CubeMeta(grid=scene.spectral_grid.to_dict(), emission=list(emission), emission_name=emission_name,
                    renderer=renderer, spp=settings.spp, seed=settings.seed, scene_hash=scene.scene_hash,
                    view_hash=scene.view_hash(job.view), render_stats=stats, group_kind=scene.group_kind(job.group),
                    units="radiance per unit emission (band averages)",
                    **({"generator": dict(scene.generator)} if scene.generator else {}))


def store_result(st, scene: Scene, job: Job, result, settings, overwrite: bool, extra_stats: dict,
                 prepared: tuple | None = None) -> bool:
    """Write a rendered cube (with its illumination cube and denoised copies) into the store, or
    record it as empty when it is all zero. Returns True for empty. ``prepared``: the
    :func:`denoise_guides` of this job, when already traced."""
    from illumix.renderer_jobs.mitsuba.render import ILLUMINATION_METHOD
    from illumix.store.schema import IlluminationInfo

    meta = cube_meta(scene, job, settings, result.emission.tolist(), result.emission_name, result.renderer,
                     {**result.stats, **extra_stats})
    if result.illumination is not None:
        meta.illumination = IlluminationInfo(method=result.renderer.get("illumination_method", ILLUMINATION_METHOD))
    if not (result.cube.max() > 0):
        # Nothing of this group reaches the view (e.g. a lamp behind the camera lighting nothing seen).
        st.mark_empty(scene.name, job.view, job.group, meta, overwrite=overwrite)
        return True
    denoised = _denoise(st, scene, job, result, settings, meta, prepared)
    st.write_cube(scene.name, job.view, job.group, result.cube, meta, overwrite=overwrite,
                  illumination=result.illumination, denoised=denoised)
    return False


def denoise_guides(st, scene, job, settings) -> tuple:
    """``(Guides, guide_passes)`` of ``settings.denoise`` for a cube job: the view's stored AOVs, plus
    what only the renderer can make (:mod:`renderer_jobs.mitsuba.denoise_guides`): the group's direct-light
    guide, and the per-band albedo and the straddle AOV of a view stored without them (e.g. by
    Cycles, or before they existed), traced once and added to the view. ``guide_passes`` records what was traced."""
    from illumix.renderer_jobs.mitsuba import denoise_guides as dg
    from illumix.renderer_jobs.mitsuba.trace import Tracer
    from illumix.retarget.denoise import Guides

    wanted = dg.guides_needed(settings)
    view_meta = st.view_meta(scene.name, job.view)
    # the straddle AOV only where it is wanted (the view may hold it from a boosted render)
    names = ("albedo", "albedo_bands", "normal", "depth", "mask", "emitter",
             *(("straddle",) if "straddle" in wanted else ()))
    aovs = {n: st.read_aov(scene.name, job.view, n) for n in names if n in view_meta.aovs}
    extra: dict = {}
    traced = {name: (fn, rays) for name, fn, rays in (("albedo_bands", dg.albedo_bands, dg.ALBEDO_RAYS),
                                                      ("straddle", dg.straddle, dg.STRADDLE_RAYS))
              if name in wanted and name not in aovs}
    if traced:
        tracer = Tracer(scene, job.view, None, settings.resolution)
        for name, (fn, rays) in traced.items():
            aovs[name] = fn(tracer)
            extra[name] = f"traced for denoising ({rays} rays per pixel) and added to the view"
        st.write_view(scene.name, job.view, view_meta, {n: aovs[n] for n in traced})
    guides = Guides.from_aovs(aovs)
    if "direct" in wanted:
        # the light glass keeps from each pixel: traced only where the scene has glass (0.1-0.25 s
        # CPU a group otherwise spent finding none)
        glass = any(isinstance(m, Dielectric) for m in scene.materials.values())
        traced = dg.direct_guide(scene, job.view, job.group, settings.resolution, settings.seed, behind_glass=glass)
        guides = guides.with_direct(traced.direct, traced.behind, traced.noise, traced.seen)
        extra["direct"] = {"samples_per_pixel": 2 * dg.DIRECT_SAMPLES, "seed": settings.seed, "behind_glass": glass}
    return guides, extra


def _denoise(st, scene, job, result, settings, meta, prepared: tuple | None = None) -> dict | None:
    """Denoised copies of a rendered cube (and its illumination cube) with :func:`denoise_guides`
    (``prepared``: already traced). Records the method in ``meta.denoised``. ``None`` when off."""
    method = settings.denoise
    if method is None:
        return None
    from illumix.retarget.denoise import as_rendered, denoise, describe
    from illumix.store.schema import DenoisedInfo

    t = time.perf_counter()
    guides, extra = prepared if prepared is not None else denoise_guides(st, scene, job, settings)
    if guides.direct is not None:  # the direct-light test weighs its bias against the cube's noise
        guides = guides.with_cube_noise(result.noise)
    out = {"transport": denoise(result.cube, guides, method)}
    if result.illumination is not None:
        out["illumination"] = denoise(result.illumination, guides, method, kind="illumination")
    info = describe(method)
    if guides.straddle is None:  # optional: used only with the targeted extra paths
        info["guides"] = [g for g in info["guides"] if g != "straddle"]
    kept = {k: as_rendered(guides, method, k) for k in out}
    if all(v is not None for v in kept.values()):  # what a user sees served as rendered, and why
        info["as_rendered_fraction"] = {k: round(float(v.mean()), 5) for k, v in kept.items()}
        info["tolerance"] = ("the cube's own noise (band sets' spread, pooled 5x5)" if guides.cube_noise is not None
                             else "fixed (no noise estimate for this cube)")
    meta.denoised = DenoisedInfo(**info, cost_ms=round(1e3 * (time.perf_counter() - t), 2),
                                 **({"guide_passes": extra} if extra else {}))
    return out


# ---------------------------------------------------------------------------------------------
# Executors


ProgressFn = Callable[[Job, dict | None, BaseException | None], None]


__all__ = ["EXECUTORS", "Job", "JobError", "Plan", "apply_resolution", "parse_resolution", "plan", "run_job"]
