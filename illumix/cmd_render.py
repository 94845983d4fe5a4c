"""``illumix render CONFIG --store PATH`` / ``illumix render --demo --store PATH``.

Renders every (scene, view, light group) transport cube not yet complete in the store (resume after
an interruption is just running the command again). The whole plan is validated first: a bad
config, an unknown view/group, or a store holding the scene from another description stops the run
with one line and exit 2 before anything is written.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer

from illumix.consoles import make_console
from illumix.errors import UserError, storage_errno
from illumix.options import choice_option, described, seed_option
from illumix.render_options import check_executor, render_settings, with_settings_options
from illumix.render_run import plan_estimate, print_estimate, refuse_conflicts, run_jobs, storage_failure
from illumix.renderer_jobs.modes import EXECUTORS

console = make_console(stderr=True)  # full-width tables off a terminal




def require_renderer(backend: str = "mitsuba") -> None:
    """Stop with one line when this machine cannot render with ``backend``
    (:meth:`renderer_jobs.backends.Backend.require`): Mitsuba (the optional extra ``render``) or
    Blender's environment not installed.

    A service-only install (``pip install illumix``, ``docker/Dockerfile.service``) has no renderer;
    ``scripts/install.sh`` and ``docker/Dockerfile.render`` install it.
    """
    from illumix.renderer_jobs.backends import get_backend
    from illumix.renderer_jobs.backends import RenderError
    from illumix.scene.schema import SceneError

    try:
        get_backend(backend).require()
    except (RenderError, SceneError) as exc:
        raise UserError(str(exc)) from None


def _split(text: str | None, flag: str) -> list[str] | None:
    """The names of a comma-separated option; ``None`` (all) when it is not given."""
    if text is None:
        return None
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:  # `--groups ""` or `--groups ,` would otherwise quietly mean "all"
        raise UserError(f"{flag} {text!r} names nothing; give comma-separated names, or leave {flag} out for all")
    return names


@with_settings_options
def render(
    config: Path | None = typer.Argument(None, help="Scene file (YAML or JSON; one scene or {scenes: [...]}), or a "
                                                    "scene to import: .gltf, .glb, .obj, Mitsuba .xml, .blend."),
    rules: Path | None = typer.Option(None, "--rules", help="Light-group rule file for an imported CONFIG "
                                                            "(see `illumix import`)."),
    store: str = typer.Option(..., "--store", help="Cube store directory or fsspec URL (created if missing)."),
    demo: bool = typer.Option(False, "--demo", help="Render the procedural demo room instead of CONFIG."),
    demo_seed: int = seed_option("--demo-seed", "Seed of the demo room's layout and materials."),
    resolution: str | None = typer.Option(None, "--resolution", help="WIDTHxHEIGHT for every view (e.g. 320x240)."),
    settings_options: dict | None = None,  # every RenderSettings option (--spp, --seed, …: render_options)
    views: str | None = typer.Option(None, "--views", help="Only these views (comma-separated)."),
    groups: str | None = typer.Option(None, "--groups", help="Only these light groups (comma-separated)."),
    workers: int = typer.Option(1, "--workers", min=1, help="Local worker processes."),
    executor: str = choice_option(EXECUTORS, "--executor", f"Where jobs run — {described(EXECUTORS)}."),
    address: str | None = typer.Option(None, "--address", help="Ray cluster address (ray executor)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Re-render and replace cubes already in the store."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the plan; render nothing."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON summary on stdout."),
) -> None:
    """Render spectral transport cubes (one per view and light group) into a cube store."""
    executor = check_executor(executor, address)
    scenes, settings, p = _plan(config, rules, store, demo, demo_seed, resolution, settings_options, views, groups,
                                overwrite, dry_run)
    refuse_conflicts(p, overwrite, "use another store or scene name, or --overwrite to re-render")
    summary = {"store": store, "scenes": list(p.scenes), "cubes_to_render": len(p.cube_jobs),
               "views_to_write": len(p.view_jobs), "already_complete": len([j for j in p.skipped if j.group]),
               "executor": executor, **{k: getattr(settings, k) for k in settings.cli_fields()}}
    quiet = as_json and not console.is_terminal
    est = plan_estimate(p, settings, workers, executor)
    if dry_run:
        for j in p.jobs:
            console.print(f"would render {j.label}")
        print_estimate(console, est, summary)
        if as_json:
            print(json.dumps({**summary, "jobs": [j.label for j in p.jobs]}))
        return
    print_estimate(console, est, summary, show=not quiet and bool(p.jobs))
    if not p.jobs:
        console.print(f"nothing to do: all {summary['already_complete']} cube(s) are complete in {store}")
        if as_json:
            print(json.dumps({**summary, "rendered": [], "seconds": 0.0}))
        return
    if executor == "local":
        require_renderer(settings.backend)  # ray: the workers render (their image has it); the driver needs none
    t0 = time.perf_counter()
    done, _ = run_jobs(console, p, store, settings, executor=executor, workers=workers, address=address,
                       overwrite=overwrite, quiet=quiet)
    elapsed = time.perf_counter() - t0
    empty = [d["job"] for d in done if d.get("empty")]
    console.print(f"rendered {len([d for d in done if d['kind'] == 'cube'])} cube(s) and "
                  f"{len([d for d in done if d['kind'] == 'view'])} view(s) into {store} in {elapsed:.1f} s"
                  + (f"; {len(empty)} group(s) light nothing in their view, recorded as empty" if empty else ""))
    if as_json:
        nodes = sorted({d["node"] for d in done if d.get("node")})  # the Ray nodes that ran jobs
        print(json.dumps({**summary, "rendered": [d["job"] for d in done], "empty": empty,
                          "skipped_complete": [d["job"] for d in done if d.get("skipped")],
                          **({"nodes": nodes} if nodes else {}), "seconds": round(elapsed, 3)}))


def _plan(config, rules, store, demo, demo_seed, resolution, settings_options, views, groups, overwrite, dry_run):
    """``(scenes, RenderSettings, plan)`` of the command's arguments; every problem one line."""
    from illumix.renderer_jobs import jobs
    from illumix.scene.schema import SceneError
    from illumix.scene_files import load_scene_file
    from illumix.store import StoreError

    try:
        if rules is not None and config is None:
            raise UserError("--rules applies to an imported scene file CONFIG")
        if demo == (config is not None):
            raise UserError("give either a scene file CONFIG or --demo (not both, not neither)")
        res = jobs.parse_resolution(resolution)
        if demo:
            from illumix.scene.demo import demo_room

            scenes = [demo_room(demo_seed)]
        else:
            scenes = load_scene_file(config, rules)
        scenes = [jobs.apply_resolution(s, res) for s in scenes]
        settings = render_settings(settings_options, scenes=scenes)
        if settings.backend != "mitsuba" and not dry_run:
            require_renderer(settings.backend)  # before planning: it may need another environment
        p = plan_jobs(scenes, store, views=_split(views, "--views"), groups=_split(groups, "--groups"),
                      overwrite=overwrite)
    except SceneError as exc:
        raise UserError(str(exc)) from None
    except StoreError as exc:
        raise UserError(f"store {store}: {exc}") from None
    return scenes, settings, p


def plan_jobs(scenes: list, store: str, **kw):
    """:func:`renderer_jobs.jobs.plan`, which opens (and creates) the store: a disk that refuses that
    write is one line (:func:`illumix.render_run.storage_failure`)."""
    from illumix.renderer_jobs import jobs

    try:
        return jobs.plan(scenes, store, **kw)
    except Exception as exc:
        if storage_errno(exc) is not None:
            raise storage_failure(store, exc) from None
        raise


def register(app: typer.Typer) -> None:
    app.command("render")(render)
