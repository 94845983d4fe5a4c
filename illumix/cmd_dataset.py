"""``illumix dataset CONFIG.yaml --store PATH [--scenes-dir DIR] [--dry-run] [--json] [--limit N]``.

Renders every scene of a dataset config (:mod:`illumix.dataset_config`: generated rooms and scene
files) × its views × its light groups into a cube store through the render jobs
(:func:`renderer_jobs.jobs.plan` / :func:`~renderer_jobs.execute.execute`, process pool or Ray as the
config says). Resumable: generated rooms are cached as scene files (:mod:`illumix.scene_corpus`) and
a rerun renders only the cubes not yet complete. A job that fails is reported and the others go on
(local executor); the run then exits 1 after its summary — but a disk that refuses writes (full,
read-only, failing) stops the run at once with one line and exit 2 (:mod:`illumix.render_run`): what
was complete is kept, and the same command resumes once there is space.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer

from illumix.consoles import make_console
from illumix.errors import UserError, storage_errno, write_failure
from illumix.render_run import plan_estimate, print_estimate, refuse_conflicts, run_jobs, storage_failure

console = make_console(stderr=True)  # full-width tables off a terminal


def dataset(
    config: Path = typer.Argument(..., help="Dataset config (YAML/JSON): name, generated: {count, seed, generator}, "
                                            "scenes: [files], render: {illumix render's options}."),
    store: str = typer.Option(..., "--store", help="Cube store directory or fsspec URL (created if missing)."),
    scenes_dir: Path | None = typer.Option(None, "--scenes-dir",
                                           help="Where generated rooms are cached as scene files (default: "
                                                "STORE/.illumix-scenes; required for a store given by URL)."),
    limit: int | None = typer.Option(None, "--limit", min=1, help="Only the first N scenes (generated rooms first)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Re-render and replace cubes already in the store."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Plan and print what would render; write nothing "
                                                          "(rooms not yet cached are generated in memory)."),
    as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON on stdout."),
) -> None:
    """Render a dataset: generated rooms and scene files × views × light groups, resumable."""
    from illumix.dataset_config import load_config

    t0 = time.perf_counter()
    cfg = load_config(config)
    r = cfg.render
    executor, res, opts = _checked_options(cfg, config)
    scenes_dir = _scenes_dir(store, scenes_dir, cfg, dry_run)
    quiet = as_json and not console.is_terminal
    corpus = _corpus(cfg, config, scenes_dir, limit, dry_run, quiet)
    scenes, settings, p = _plan(corpus.scenes, store, res, opts, r, overwrite)
    n_views = len(p.view_jobs) + sum(j.group is None for j in p.skipped)
    summary = _summary(cfg, store, scenes_dir, corpus, scenes, p, n_views, executor, settings)
    est = plan_estimate(p, settings, r.workers, executor)
    if dry_run:
        for j in p.jobs:
            console.print(f"would render {j.label}")
        console.print(f"dry run: {len(scenes)} scene(s), {n_views} view(s), {len(p.cube_jobs)} cube(s) to render, "
                      f"{summary['cubes_skipped']} already complete")
        print_estimate(console, est, summary)
        if as_json:
            print(json.dumps({**summary, "dry_run": True, "jobs": [j.label for j in p.jobs]}))
        return
    print_estimate(console, est, summary, show=not quiet and bool(p.jobs))
    done: list[dict] = []
    failed: list[dict] = []
    t_render = time.perf_counter()
    if p.jobs:
        if executor == "local":
            from illumix.cmd_render import require_renderer

            require_renderer(settings.backend)
        done, failed = run_jobs(console, p, store, settings, executor=executor, workers=r.workers,
                                address=r.address, overwrite=overwrite, quiet=quiet, keep_going=True)
    _report(summary, cfg, store, corpus, scenes, p, n_views, done, failed, time.perf_counter() - t0,
            time.perf_counter() - t_render, as_json)


def _checked_options(cfg, config: Path):
    """``(executor, resolution, the render options)`` of the config, checked before anything is generated."""
    from illumix.dataset_config import config_flag
    from illumix.render_options import check_executor, render_settings
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.render_settings import RenderSettings
    from illumix.scene.schema import SceneError

    r = cfg.render
    try:
        executor = check_executor(r.executor, r.address, config_flag)
        try:
            res = jobs.parse_resolution(r.resolution)
        except SceneError as exc:
            raise UserError(f"render.resolution: {exc}") from None
        opts = {name: getattr(r, name) for name in RenderSettings.cli_fields()}
        render_settings(opts, flag=config_flag)
    except SceneError as exc:
        raise UserError(f"{config}: render: {exc}") from None
    except UserError as exc:
        raise UserError(f"{config}: {exc}") from None
    return executor, res, opts


def _scenes_dir(store: str, scenes_dir: Path | None, cfg, dry_run: bool) -> Path | None:
    """Where generated rooms are cached (beside a local store by default); the store is made now:
    the scene cache lives in it, and a bad location should stop us before hours of work."""
    from illumix import scene_corpus
    from illumix.store import CubeStore, StoreError
    from illumix.store.backend import is_local

    if scenes_dir is None and is_local(store):
        scenes_dir = Path(store.removeprefix("file://")) / scene_corpus.SCENES_DIR
    elif scenes_dir is None and not dry_run and cfg.generated is not None and cfg.generated.count:
        raise UserError(f"--store {store} is a URL: give --scenes-dir DIR for the generated rooms' scene files")
    if not dry_run:
        try:
            CubeStore.open(store, mode="a")
        except Exception as exc:
            if storage_errno(exc) is not None:  # a full or read-only disk: one line, like every writer's
                raise storage_failure(store, exc) from None
            if not isinstance(exc, StoreError):
                raise
            raise UserError(f"store {store}: {exc}") from None
    return scenes_dir


def _corpus(cfg, config: Path, scenes_dir: Path | None, limit: int | None, dry_run: bool, quiet: bool):
    """The config's scenes (rooms generated or read from the cache, scene files), with a progress bar."""
    from illumix import scene_corpus
    from illumix.progress import progress_bar

    with progress_bar(console, disable=quiet, transient=True) as prog:  # an error after it stays one line
        task, count = None, [0, 0]
        lines = not (quiet or dry_run or console.is_terminal)  # logs, CI: a line per room (rooms take seconds)

        def on_start(n: int) -> None:
            nonlocal task
            count[1] = n
            if n:
                task = prog.add_task("scenes", total=n, last="")

        def on_room(name: str, status: str) -> None:
            count[0] += 1
            prog.update(task, advance=1, last=f"{name} {status}")
            if lines:
                console.print(f"[{count[0]}/{count[1]}] scene {name}: {status}", markup=False, highlight=False)

        try:
            corpus = scene_corpus.build(cfg, config.parent, scenes_dir, limit=limit, write=not dry_run,
                                        on_room=on_room, on_start=on_start)
        except OSError as exc:  # the rooms' scene files are written atomically: none is left half-written
            if storage_errno(exc) is None:
                raise
            raise UserError(write_failure(exc.filename or scenes_dir, exc, elsewhere="give another --scenes-dir",
                                          rerun="run the same command again: the rooms written are kept")) from None
    if corpus.generated or corpus.cached:
        console.print(f"rooms: {corpus.generated} generated, {corpus.cached} cached in {scenes_dir or '(memory)'}",
                      highlight=False)
    return corpus


def _plan(scenes: list, store: str, res, opts: dict, r, overwrite: bool):
    """``(scenes at the config's resolution, RenderSettings, plan)``; every problem one line."""
    from illumix.cmd_render import plan_jobs
    from illumix.dataset_config import config_flag
    from illumix.render_options import render_settings
    from illumix.renderer_jobs import jobs
    from illumix.scene.schema import SceneError
    from illumix.store import StoreError

    try:
        scenes = [jobs.apply_resolution(s, res) for s in scenes]
        settings = render_settings(opts, scenes=scenes, flag=config_flag)
        p = plan_jobs(scenes, store, views=r.views, groups=r.groups, overwrite=overwrite)
    except SceneError as exc:
        raise UserError(str(exc)) from None
    except StoreError as exc:
        raise UserError(f"store {store}: {exc}") from None
    refuse_conflicts(p, overwrite, "use another store, or --overwrite to re-render")
    return scenes, settings, p


def _summary(cfg, store, scenes_dir, corpus, scenes, p, n_views, executor, settings) -> dict:
    from illumix.scenegen import GENERATOR_VERSION

    return {"name": cfg.name, "store": store, "scenes_dir": str(scenes_dir) if scenes_dir else None,
            "generator_version": GENERATOR_VERSION, "scenes": len(scenes), "rooms_generated": corpus.generated,
            "rooms_cached": corpus.cached, "scene_files": corpus.files, "views": n_views,
            "cubes_planned": len(p.cube_jobs), "cubes_skipped": len([j for j in p.skipped if j.group]),
            "executor": executor, "workers": cfg.render.workers, "settings": settings.to_dict(),
            "views_dropped": views_dropped(scenes)}


def views_dropped(scenes) -> int:
    """Candidate views the generator dropped for too little mixed light (scenegen.views.MixedLightRule),
    as generated rooms record it (``generator.views_dropped``; 0 where not recorded)."""
    return sum(int((getattr(s, "generator", None) or {}).get("views_dropped", 0) or 0) for s in scenes)


def _report(summary, cfg, store, corpus, scenes, p, n_views, done, failed, wall, render_wall, as_json) -> None:
    """The run's one-line summary (and JSON); exit 1 when jobs failed (the rest are kept)."""
    cubes = [d for d in done if d["kind"] == "cube"]
    lit = [d for d in cubes if not d.get("empty")]
    cpu = [d["cpu_s"] for d in done if d.get("cpu_s") is not None]
    summary.update({
        "cubes_rendered": len(lit), "cubes_empty": len([d for d in cubes if d.get("empty")]),
        "views_written": len([d for d in done if d["kind"] == "view"]), "failed": failed,
        "wall_s": round(wall, 3), "render_wall_s": round(render_wall, 3),
        "cpu_s": round(sum(cpu), 3) if cpu and len(cpu) == len(done) else None,
        "cube_mean_s": round(sum(d["seconds"] for d in lit) / len(lit), 3) if lit else None,
    })
    if not p.jobs:
        console.print(f"nothing to do: all {summary['cubes_skipped']} cube(s) of {len(scenes)} scene(s) are "
                      f"complete in {store}")
    else:
        console.print(
            f"dataset {cfg.name}: {len(scenes)} scene(s) ({corpus.generated} generated, {corpus.cached} cached, "
            f"{corpus.files} file(s)), {n_views} view(s); cubes: {summary['cubes_rendered']} rendered, "
            f"{summary['cubes_empty']} empty, {summary['cubes_skipped']} already complete, {len(failed)} failed; "
            f"{wall:.1f} s wall" + (f", {summary['cpu_s']:.1f} s CPU" if summary["cpu_s"] is not None else "")
            + (f", {summary['cube_mean_s']:.2f} s per cube" if summary["cube_mean_s"] is not None else "")
            + (f"; {summary['views_dropped']} candidate view(s) dropped for too little mixed light"
               if summary["views_dropped"] else ""),
            highlight=False)
    if as_json:
        print(json.dumps(summary))
    if failed:
        console.print(f"{len(failed)} job(s) failed (listed above); the rest are in the store — run again to retry",
                      highlight=False)
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    app.command("dataset")(dataset)
