"""Scene description, part 3: files ↔ :class:`~scene.model.Scene`.

A YAML or JSON file holds one scene, or ``{scenes: [...]}`` several, in a format version
(``schema_version``) this illumix reads: older ones are migrated (:mod:`scene.migrate`), newer ones
refused. The format is published as a JSON Schema (:mod:`scene.json_schema`). Loading validates everything —
names that must resolve (materials, light groups, library spectra, files) included — and reports
every problem as ``<file>: <object path> (<name>): <field>: <what is wrong>`` on one line
(:class:`~scene.schema.SceneError`).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from illumix.scene.migrate import migrate
from illumix.scene.model import Scene
from illumix.scene.schema import SceneError


def _format_loc(doc: Any, loc: tuple) -> str:
    """``shapes[3] (ball).radius`` from a pydantic error location, naming objects by their name."""
    parts: list[str] = []
    node = doc
    for key in loc:
        if isinstance(key, int):
            name = node[key].get("name") if isinstance(node, list) and key < len(node) and isinstance(
                node[key], dict) else None
            parts[-1:] = [f"{parts[-1] if parts else ''}[{key}]" + (f" ({name})" if name else "")]
            node = node[key] if isinstance(node, list) and key < len(node) else None
        else:
            if isinstance(node, dict) and key in node:
                node = node[key]
            elif isinstance(node, dict):
                # Tagged-union branch names (e.g. 'rectangle', 'diffuse') are not document keys.
                if key in ("rectangle", "cube", "disk", "sphere", "cylinder", "obj", "ply", "point",
                           "spot", "directional", "constant", "envmap", "diffuse", "roughplastic",
                           "roughconductor", "dielectric", "spectrum", "pattern", "bitmap") or key.endswith(("Spectrum", "Texture", "Spectrum]")) or key.startswith("function-") or key in (
                               "str", "list[float]", "float", "tuple[float, float, float]"):
                    continue
                node = None
            else:
                node = None
            parts.append(str(key))
    return ".".join(parts) if parts else "(top level)"


def _format_errors(doc: Any, exc: ValidationError, source: str) -> str:
    msgs = []
    for err in exc.errors():
        loc = _format_loc(doc, tuple(err["loc"]))
        msg = err["msg"].removeprefix("Value error, ")
        if err.get("type") in ("union_tag_invalid", "union_tag_not_found"):
            tag = str((err.get("ctx") or {}).get("discriminator", "")).strip("'")
            loc = f"{loc}.{tag}" if loc != "(top level)" else tag
        msgs.append(f"{loc}: {msg}" if loc != "(top level)" else msg)
    # Union branches repeat the same location; keep each message once.
    unique = list(dict.fromkeys(msgs))
    return f"{source}: " + "; ".join(unique[:8]) + (f"; … {len(unique) - 8} more" if len(unique) > 8 else "")


def scene_from_dict(doc: Any, *, source: str = "scene", base: Path | None = None,
                    check: bool = True) -> Scene:
    """Validate a parsed document (one scene) into a :class:`Scene`; :class:`SceneError` if bad.

    An older format version is migrated first (:func:`scene.migrate.migrate`; each change a warning), a
    newer one refused with one line naming the versions this illumix reads."""
    if not isinstance(doc, dict):
        raise SceneError(f"{source}: a scene must be a mapping, got {type(doc).__name__}")
    try:
        doc, notes = migrate(doc, source)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    for note in notes:
        warnings.warn(note, stacklevel=2)
    try:
        scene = Scene.model_validate(doc)
    except ValidationError as exc:
        raise SceneError(_format_errors(doc, exc, source)) from None
    scene = scene.with_base(base)
    if check:
        try:
            scene.check_resources()
        except SceneError as exc:
            raise SceneError(f"{source}: scene {scene.name!r}: {exc}") from None
    return scene


def load_scenes(path: str | Path, *, check: bool = True) -> list[Scene]:
    """Load a YAML or JSON file holding one scene or ``{scenes: [...]}`` (other formats are imported:
    :data:`scene_import.IMPORTERS`)."""
    p = Path(path)
    if p.suffix.lower() == ".blend":
        raise SceneError(f"{p} is a Blender file: import it (illumix.scene_import.load_file, or give it to "
                         "`illumix render` / `illumix import`)")
    if not p.is_file():
        what = "is a directory; give a YAML or JSON file" if p.is_dir() else "does not exist"
        raise SceneError(f"scene file {str(p)!r} {what}")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{p}: cannot read ({exc})") from None
    try:
        doc = json.loads(text) if p.suffix.lower() == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        first = str(exc).strip().splitlines()
        raise SceneError(f"{p}: not valid {'JSON' if p.suffix.lower() == '.json' else 'YAML'}: "
                         f"{' '.join(s.strip() for s in first)}") from None
    docs = doc["scenes"] if isinstance(doc, dict) and "scenes" in doc and len(doc) == 1 else [doc]
    if not isinstance(docs, list) or not docs:
        raise SceneError(f"{p}: 'scenes' must be a non-empty list")
    scenes = [scene_from_dict(d, source=f"{p}" + (f" scenes[{i}]" if len(docs) > 1 else ""),
                              base=p.parent.resolve(), check=check) for i, d in enumerate(docs)]
    names = [s.name for s in scenes]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SceneError(f"{p}: duplicate scene names {sorted(dup)}")
    return scenes


def dump_scene(scene: Scene, path: str | Path) -> None:
    """Write a scene as YAML (``.yaml``/``.yml``) or JSON."""
    p = Path(path)
    doc = scene.model_dump(mode="json", exclude_defaults=False)
    if p.suffix.lower() == ".json":
        p.write_text(json.dumps(doc, indent=1))
    else:
        p.write_text(yaml.safe_dump(doc, sort_keys=False))
