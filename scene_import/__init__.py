"""Importers: existing scenes (glTF 2.0, Wavefront OBJ + MTL, Mitsuba XML, Blender .blend) as illumix scenes.

One registry keyed by file extension (:data:`IMPORTERS`). :func:`import_scene` converts a glTF, OBJ
or Mitsuba XML file into a scene document (a dict the schema validates:
:func:`scene.load.scene_from_dict`) plus the list of warnings — everything the
importer could not represent, each naming the object (never a silent wrong colour). Meshes and
texture images are written under ``out_dir/<assets>/`` and referenced relative to ``out_dir``, where
the scene file belongs. Names become renderer-safe unique keys (:mod:`scene_import.names`: ``Cube.001`` →
``Cube_001``, the originals in ``generator.renamed``). Light groups: daylight / warm / cool by light kind
and colour temperature (:mod:`scene_import.grouping`), or a rule file (:mod:`scene_import.rules`).
An import with nothing renderable (no shape; no emitter, unless a sky is asked for) is refused.
"""

from __future__ import annotations

from pathlib import Path

from illumix.scene.spectra import SceneError

#: file extension → importer. "document" importers write a scene document and its assets into a
#: folder (:func:`import_scene`; the CLI caches it: illumix/scene_files.py); "blend" reads the file
#: with Blender (:func:`scene_import.blend.load_blend`, which caches Blender's export itself).
IMPORTERS = {".gltf": "gltf", ".glb": "gltf", ".obj": "obj", ".xml": "mitsuba", ".blend": "blend"}
SUPPORTED = {ext: fmt for ext, fmt in IMPORTERS.items() if fmt != "blend"}  # the document importers


def load_file(path: str | Path, rules=None, out_dir: str | Path | None = None, sky: bool = False) -> list:
    """The scenes of any importable file (:data:`IMPORTERS`), validated: a ``.blend`` through Blender,
    the others converted into ``out_dir`` (default: a temporary folder) and loaded from there.
    ``rules`` applies to the document importers."""
    import tempfile

    from illumix.scene.load import load_scenes

    p = Path(path)
    fmt = IMPORTERS.get(p.suffix.lower())
    if fmt == "blend":
        if rules is not None:
            raise SceneError(f"a rule file applies to {', '.join(SUPPORTED)} imports, not {p.suffix!r}")
        from illumix.scene_import.blend import load_blend

        return load_blend(p)
    out = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="illumix-import-"))
    doc, _ = import_scene(p, out, rules, sky=sky)
    import yaml

    (out / "scene.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return load_scenes(out / "scene.yaml")


def import_scene(path: str | Path, out_dir: str | Path, rules=None, *, assets: str | None = None,
                 sky: bool = False) -> tuple[dict, list[str]]:
    """``(scene document, warnings)`` of a ``.gltf``/``.glb``/``.obj``/``.xml`` file.

    ``rules``: a :class:`scene_import.rules.Rules`, a path to a rule file, or None (the default
    grouping by light kind and colour temperature: :mod:`scene_import.grouping`). ``assets``: the
    sub-folder of ``out_dir`` for meshes and images (default ``<file stem>_assets``). ``sky``: light a
    file without emitters by a constant sky instead of refusing it. Raises :class:`SceneError` (one
    line) for files it cannot read and for imports with nothing renderable (no shape; no emitter).
    """
    from illumix.scene_import.builder import SceneBuilder
    from illumix.scene_import.names import key_name
    from illumix.scene_import.rules import Rules, load_rules

    p = Path(path)
    fmt = SUPPORTED.get(p.suffix.lower())
    if IMPORTERS.get(p.suffix.lower()) == "blend":
        raise SceneError(f"{p}: a Blender file is read by Blender where it is used, not converted: give it to "
                         f"`illumix render` (or scene_import.load_file); this converts {', '.join(SUPPORTED)}")
    if fmt is None:
        raise SceneError(f"{p}: cannot import {p.suffix or 'a file without extension'!r}; supported: "
                         f"{', '.join(IMPORTERS)} (and .yaml/.yml/.json scene files)")
    if not p.is_file():
        raise SceneError(f"{p}: {'is a directory' if p.is_dir() else 'does not exist'}")
    if rules is not None and not isinstance(rules, Rules):
        rules = load_rules(rules)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    b = SceneBuilder(out_dir=out, assets=assets or f"{key_name(p.stem, 'scene')}_assets", source=p, fmt=fmt)
    if fmt == "gltf":
        from illumix.scene_import.gltf import import_gltf as run
    elif fmt == "obj":
        from illumix.scene_import.obj import import_obj as run
    else:
        from illumix.scene_import.mitsuba_xml import import_mitsuba_xml as run
    try:
        name = run(p, b)
    except SceneError:
        raise
    except (ValueError, KeyError, IndexError, TypeError, AttributeError, ArithmeticError, OSError) as exc:
        # a malformed file (bad numbers, dangling indices, missing referenced files): one line, not a traceback
        raise SceneError(f"{p}: cannot import this {fmt} file ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:300]})") from None
    doc = b.finish(name, rules, description=f"imported from {p.name} ({fmt})", sky=sky)
    return doc, list(b.warnings)


__all__ = ["SUPPORTED", "import_scene"]
