"""Importers: existing scenes (glTF 2.0, Wavefront OBJ + MTL, Mitsuba 3 XML) as illumix scene documents.

:func:`import_scene` converts one file into a scene document (a dict the schema validates:
:func:`renderer_jobs.scene_load.scene_from_dict`) plus the list of warnings — everything the
importer could not represent, each naming the object (never a silent wrong colour). Meshes and
texture images are written under ``out_dir/<assets>/`` and referenced relative to ``out_dir``, where
the scene file belongs. Light groups come from a rule file (:mod:`scene_import.rules`).
"""

from __future__ import annotations

from pathlib import Path

from illumix.renderer_jobs.scene_spectra import SceneError

SUPPORTED = {".gltf": "gltf", ".glb": "gltf", ".obj": "obj", ".xml": "mitsuba"}


def import_scene(path: str | Path, out_dir: str | Path, rules=None, *, assets: str | None = None
                 ) -> tuple[dict, list[str]]:
    """``(scene document, warnings)`` of a ``.gltf``/``.glb``/``.obj``/``.xml`` file.

    ``rules``: a :class:`scene_import.rules.Rules`, a path to a rule file, or None (one group per
    light). ``assets``: the sub-folder of ``out_dir`` for meshes and images (default
    ``<file stem>_assets``). Raises :class:`SceneError` (one line) for files it cannot read.
    """
    from illumix.renderer_jobs.blend_import import sanitize
    from illumix.scene_import.builder import SceneBuilder
    from illumix.scene_import.rules import Rules, load_rules

    p = Path(path)
    fmt = SUPPORTED.get(p.suffix.lower())
    if fmt is None:
        raise SceneError(f"{p}: cannot import {p.suffix or 'a file without extension'!r}; supported: "
                         f"{', '.join(SUPPORTED)} (and .yaml/.yml/.json scene files, .blend)")
    if not p.is_file():
        raise SceneError(f"{p}: {'is a directory' if p.is_dir() else 'does not exist'}")
    if rules is not None and not isinstance(rules, Rules):
        rules = load_rules(rules)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    b = SceneBuilder(out_dir=out, assets=assets or f"{sanitize(p.stem, 'scene')}_assets", source=p, fmt=fmt)
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
    doc = b.finish(name, rules, description=f"imported from {p.name} ({fmt})")
    return doc, list(b.warnings)


__all__ = ["SUPPORTED", "import_scene"]
