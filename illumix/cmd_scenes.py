"""``illumix scenes generate`` (procedural rooms as scene files) and ``illumix scenes preview``
(a contact sheet of quick low-spp renders, to look before spending hours)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from illumix.consoles import make_console
from illumix.errors import UserError

console = make_console(stderr=True)
scenes_app = typer.Typer(help="Generate procedural rooms; preview scenes before rendering them.",
                         no_args_is_help=True)


def _generator_config(path: Path | None, probe: bool):
    """The :class:`~scenegen.generate.GeneratorConfig` of ``--config`` (a generator mapping, or a
    dataset config whose ``generated.generator`` is used), with ``--no-probe`` applied."""
    from pydantic import ValidationError

    from illumix.dataset_config import _hint, is_dataset_config, parse_config, read_doc
    from illumix.scenegen.generate import GeneratorConfig

    doc = {} if path is None else read_doc(path)
    if doc is None:
        doc = {}
    if is_dataset_config(doc):
        cfg = parse_config(doc, str(path))
        gen = cfg.generated.generator if cfg.generated is not None else GeneratorConfig()
    else:
        if not isinstance(doc, dict):
            raise UserError(f"{path}: a generator config is a mapping (layouts, windows, views, resolution, "
                            f"probe, candidates); got {type(doc).__name__}")
        try:
            gen = GeneratorConfig.model_validate(doc)
        except ValidationError as exc:
            errs = exc.errors()
            raise UserError(f"{path}: {_hint(errs[0])}" + (f" (and {len(errs) - 1} more)" if len(errs) > 1 else "")) \
                from None
    return gen.model_copy(update={"probe": False}) if not probe else gen


@scenes_app.command("generate")
def generate(
    count: int = typer.Option(..., "--count", min=1, max=1_000_000, help="How many rooms."),
    seed: int = typer.Option(0, "--seed", min=0, max=999_999, help="First seed: rooms SEED .. SEED+COUNT-1."),
    out: Path = typer.Option(..., "--out", help="Folder for the scene files (room-NNNNNN.yaml; created)."),
    config: Path | None = typer.Option(None, "--config", help="Generator config YAML (layouts, windows, views, "
                                                              "resolution, probe, candidates) or a dataset config."),
    probe: bool = typer.Option(True, "--probe/--no-probe", help="Choose views by a probe render's mixed-light "
                                                                "fraction (seconds per room); --no-probe: the first "
                                                                "candidates."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON summary on stdout."),
) -> None:
    """Write COUNT procedural rooms as scene files `illumix render` accepts (existing ones are kept: resume)."""
    import time

    from illumix import scene_corpus
    from illumix.progress import progress_bar

    if seed + count > 1_000_000:
        raise UserError(f"--seed {seed} + --count {count} must be <= 1000000 (room names are room-NNNNNN)")
    gen = _generator_config(config, probe)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} is a file; give a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"--out {out}: cannot create ({exc.strerror})") from None
    t0 = time.perf_counter()
    counts = {"generated": 0, "regenerated": 0, "cached": 0}
    with progress_bar(console, disable=as_json and not console.is_terminal) as prog:
        task = prog.add_task("rooms", total=count, last="")
        for s in range(seed, seed + count):
            scene, status = scene_corpus.room(s, gen, out)
            counts[status] += 1
            prog.update(task, advance=1, last=f"{scene.name} {status}")
    wall = time.perf_counter() - t0
    made = counts["generated"] + counts["regenerated"]
    console.print(f"{count} room(s) in {out}: {made} generated"
                  + (f" ({counts['regenerated']} replaced: other generator version or config)"
                     if counts["regenerated"] else "")
                  + f", {counts['cached']} already there; {wall:.1f} s"
                  + (f" ({wall / made:.2f} s per room)" if made else ""), highlight=False)
    if as_json:
        from illumix.scenegen import GENERATOR_VERSION

        print(json.dumps({"out": str(out), "count": count, "seed": seed, "generator_version": GENERATOR_VERSION,
                          "config": gen.model_dump(mode="json"), **counts, "seconds": round(wall, 3),
                          "files": [f"{scene_corpus.room_name(s)}.yaml" for s in range(seed, seed + count)]}))


def _parse_size(text: str) -> tuple[int, int]:
    from illumix.renderer_jobs.jobs import parse_resolution
    from illumix.scene.schema import SceneError

    try:
        w, h = parse_resolution(text)
    except SceneError as exc:
        raise UserError(f"--size: {exc}") from None
    if w < 8 or h < 8 or w * h > 1024 * 1024:
        raise UserError(f"--size {text}: give 8x8 .. 1024x1024 pixels per tile (e.g. 160x120)")
    return w, h


def _preview_scenes(inputs: list[Path], max_scenes: int | None, scenes_dir: Path | None):
    """The scenes named by ``inputs`` (dataset configs and scene files), at most ``max_scenes``."""
    from illumix import scene_corpus
    from illumix.dataset_config import is_dataset_config, parse_config, read_doc
    from illumix.scene_files import load_scene_file
    from illumix.scene.schema import SceneError

    scenes = []
    for path in inputs:
        left = None if max_scenes is None else max_scenes - len(scenes)
        if left is not None and left <= 0:
            break
        doc = read_doc(path) if path.suffix.lower() in (".yaml", ".yml", ".json") else None
        if is_dataset_config(doc):
            cfg = parse_config(doc, str(path))
            with console.status(f"scenes of {path}"):
                corpus = scene_corpus.build(cfg, path.parent, scenes_dir, limit=left, write=scenes_dir is not None)
            scenes += corpus.scenes
        else:
            try:
                got = load_scene_file(path)
            except SceneError as exc:
                raise UserError(str(exc)) from None
            scenes += got[:left]
    return scenes


@scenes_app.command("preview")
def preview(
    inputs: list[Path] = typer.Argument(..., help="Dataset configs and/or scene files."),
    out: Path = typer.Option(..., "--out", help="Contact sheet PNG to write."),
    spp: int = typer.Option(16, "--spp", min=1, max=4096, help="Paths per pixel of each preview."),
    size: str = typer.Option("160x120", "--size", help="WIDTHxHEIGHT of each view's tile."),
    max_scenes: int | None = typer.Option(None, "--max-scenes", min=1, help="Only the first N scenes."),
    scenes_dir: Path | None = typer.Option(None, "--scenes-dir", help="Cache of a config's generated rooms (e.g. "
                                                                      "STORE/.illumix-scenes; default: generate "
                                                                      "in memory, write nothing)."),
) -> None:
    """Write a contact sheet PNG of quick renders of every view of the scenes (labelled scene/view groups)."""
    from illumix.cmd_render import require_renderer
    from illumix.progress import progress_bar

    if out.suffix.lower() != ".png":
        raise UserError(f"--out {out}: give a .png file name")
    if not out.parent.is_dir():
        raise UserError(f"--out {out}: folder {str(out.parent)!r} does not exist")
    w, h = _parse_size(size)
    for p in inputs:
        if not p.is_file():
            raise UserError(f"{p}: " + ("is a directory; give YAML/JSON files" if p.is_dir() else "does not exist"))
    scenes = _preview_scenes(inputs, max_scenes, scenes_dir)
    if not scenes:
        raise UserError("no scenes to preview")
    require_renderer()
    import cv2
    import numpy as np

    from illumix.renderer_jobs.mitsuba.preview import contact_sheet, preview_linear, to_srgb8

    per_row = max(len(s.views) for s in scenes)
    columns = per_row if per_row <= 8 else 4
    tiles: list[tuple[str, np.ndarray]] = []
    blank = np.full((h, w, 3), 32, np.uint8)
    with progress_bar(console) as prog:
        task = prog.add_task("previews", total=len(scenes), last="")
        for s in scenes:
            views = [v.name for v in s.views]
            lin = preview_linear(s, views, (w, h), spp)
            groups = len(s.group_names)
            for v, img in zip(views, lin):
                tiles.append((f"{s.name}/{v} {groups}g", to_srgb8(img)))  # 3g: three light groups
            if columns == per_row:  # one scene per row
                tiles += [("", blank)] * (columns - len(views))
            prog.update(task, advance=1, last=s.name)
    sheet = contact_sheet(tiles, columns=columns)
    if not cv2.imwrite(str(out), sheet[..., ::-1]):
        raise UserError(f"--out {out}: cannot write the PNG")
    console.print(f"wrote {out}: {len(scenes)} scene(s), {sum(len(s.views) for s in scenes)} view(s), "
                  f"{sheet.shape[1]}x{sheet.shape[0]} px", highlight=False)


@scenes_app.command("schema")
def schema(out: Path | None = typer.Option(None, "--out", help="Write it to this file instead of stdout.")) -> None:
    """Print the scene format's JSON Schema (docs/scene.schema.json; format version and migration: docs/scene-format.md)."""
    from illumix.scene.json_schema import schema_text

    text = schema_text()
    if out is None:
        print(text, end="")
        return
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UserError(f"--out {out}: cannot write ({exc.strerror or exc}); choose a writable path") from None
    console.print(f"wrote {out}", highlight=False)


def register(app: typer.Typer) -> None:
    app.add_typer(scenes_app, name="scenes")
