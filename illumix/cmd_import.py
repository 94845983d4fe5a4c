"""``illumix import FILE --out SCENE.yaml [--rules RULES.yaml] [--sky]``: convert a glTF (``.gltf``/``.glb``),
OBJ + MTL or Mitsuba XML scene into an illumix scene file (:mod:`scene_import`).

Meshes and images go to ``<SCENE stem>_assets/`` beside ``SCENE.yaml``. Everything is written into a
temporary folder first, validated against the schema, then renamed into place: a failed import
leaves nothing behind and an earlier output intact. An import with nothing renderable (no shape, or
no emitter without ``--sky``) is refused: one line, exit 2. Warnings (what could not be represented) go to
stderr, one line each; the summary line goes to stdout (``--json``: a JSON object instead).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

import typer

from illumix.errors import UserError


def import_cmd(
    file: Path = typer.Argument(..., help="Scene to import: .gltf, .glb, .obj (with its .mtl) or Mitsuba .xml "
                                           "(3; legacy 0.5/2.x upgraded)."),
    out: Path = typer.Option(..., "--out", help="Scene file to write (.yaml, .yml or .json); meshes and images "
                                                "go to <stem>_assets/ beside it."),
    rules: Path | None = typer.Option(None, "--rules", help="Light-group rule file (YAML: groups with fnmatch "
                                                            "patterns, optional illuminant; default_group; "
                                                            "grouping: kind|each). Default: daylight / warm / "
                                                            "cool groups by light kind and colour temperature."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON summary (with the warnings) on stdout."),
    sky: bool = typer.Option(False, "--sky", help="Light a file that has no lights with a constant D65 sky "
                                                  "(without it such a file is refused, exit 2)."),
) -> None:
    """Convert a glTF / OBJ / Mitsuba XML scene into an illumix scene file."""
    from illumix.scene_files import write_yaml
    from illumix.scene.load import scene_from_dict
    from illumix.scene.spectra import SceneError
    from illumix.scene_import import import_scene

    if out.suffix.lower() not in (".yaml", ".yml", ".json"):
        raise UserError(f"--out {str(out)!r}: give a .yaml, .yml or .json file name")
    if out.is_dir():
        raise UserError(f"--out {str(out)!r} is a directory; give a scene file name")
    parent = out.parent if str(out.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"--out {str(out)!r}: cannot create folder {str(parent)!r} ({exc.strerror})") from None
    assets = f"{out.stem}_assets"
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=parent))
    try:
        try:
            doc, warns = import_scene(file, tmp, rules, assets=assets, sky=sky)
            scene = scene_from_dict(doc, source=str(file), base=tmp)
            if not scene.shapes or not scene.group_names:  # the importers refuse these; a last guard
                raise SceneError(f"{file}: nothing to render: {'no shapes' if not scene.shapes else 'no emitters'}")
        except SceneError as exc:
            raise UserError(str(exc)) from None
        write_yaml(doc, tmp / out.name)
        final = parent / assets
        if (tmp / assets).is_dir():
            old = parent / f".{assets}.old-{os.getpid()}"
            if final.exists():
                final.rename(old)
            (tmp / assets).rename(final)
            shutil.rmtree(old, ignore_errors=True)
        os.replace(tmp / out.name, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for w in warns:
        print(f"illumix: warning: {w}", file=sys.stderr)
    summary = {"out": str(out), "scene": scene.name, "shapes": len(scene.shapes), "lights": len(scene.lights),
               "materials": len(scene.materials), "groups": scene.group_names, "views": [v.name for v in scene.views],
               "warnings": warns}
    if as_json:
        print(json.dumps(summary))
    else:
        print(f"imported {file.name} -> {out}: {len(scene.shapes)} shapes, {len(scene.materials)} materials, "
              f"{len(scene.lights)} lights, {len(scene.group_names)} light groups "
              f"({', '.join(scene.group_names)}), {len(scene.views)} views; {len(warns)} warning(s)")


def register(app: typer.Typer) -> None:
    app.command("import")(import_cmd)
