"""Scene files the CLI accepts: illumix YAML/JSON (and ``.blend``) as they are, and glTF / OBJ / Mitsuba XML
through :mod:`scene_import`.

An imported file is converted once into a cache directory — ``.illumix-import/<stem>-<key>/`` beside
the file (or ``$ILLUMIX_CACHE/import/`` when that folder is not writable), ``key`` a sha256 of the
file's bytes, the rule file's and the importer's sources — holding ``scene.yaml``, its meshes and
images, and ``warnings.json``. A later load of the same file reuses it and repeats its warnings.
Files the imported one references (glTF buffers and images, MTL, XML meshes) are not part of the key:
delete the cache directory after changing only them.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import warnings
from pathlib import Path

NATIVE = (".yaml", ".yml", ".json")  # illumix scene files; the importable ones: scene_import.IMPORTERS


def _key(path: Path, rules: Path | None) -> str:
    from illumix import scene_import

    h = hashlib.sha256(path.read_bytes())
    for f in _companions(path):  # an edited include, MTL, mesh or texture beside it is a new import too
        st = f.stat()
        h.update(f"{f.relative_to(path.parent)}:{st.st_size}:{st.st_mtime_ns}".encode())
    if rules is not None:
        h.update(b"rules" + Path(rules).read_bytes())
    for src in sorted(Path(scene_import.__file__).parent.glob("*.py")):
        h.update(src.read_bytes())
    return h.hexdigest()[:16]


#: At most this many files under a scene file's folder take part in its import's cache key.
COMPANION_LIMIT = 2000


#: What an importer may read beside a scene file: meshes, materials, includes, textures, spectra.
COMPANION_SUFFIXES = frozenset({".obj", ".mtl", ".ply", ".serialized", ".xml", ".gltf", ".glb", ".bin", ".png",
                                ".jpg", ".jpeg", ".exr", ".hdr", ".tga", ".bmp", ".tif", ".tiff", ".csv", ".spd"})


def _companions(path: Path) -> list[Path]:
    """The files under ``path``'s folder an import may read (:data:`COMPANION_SUFFIXES`), sorted;
    none when there are more than :data:`COMPANION_LIMIT` (a scene file in a large folder, e.g. a
    home directory: then only the file itself counts). Hidden folders (the import caches) and cube
    stores (a folder holding ``zarr.json``) are not looked into: a store rendered beside the scene
    changes with every render, and would make every load a new import."""
    out = []
    for root, dirs, files in os.walk(path.parent):
        if "zarr.json" in files:
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in files:
            f = Path(root) / name
            if f.suffix.lower() in COMPANION_SUFFIXES and f != path:
                out.append(f)
                if len(out) > COMPANION_LIMIT:
                    return []
    return sorted(out)


def _cache_dir(path: Path, key: str) -> Path:
    local = path.parent / ".illumix-import"
    if os.access(path.parent, os.W_OK):
        return local / f"{path.stem}-{key}"
    root = Path(os.environ.get("ILLUMIX_CACHE", Path.home() / ".cache" / "illumix")) / "import"
    return root / f"{path.stem}-{key}"


def import_cached(path: str | Path, rules: str | Path | None = None) -> tuple[Path, list[str]]:
    """``(scene.yaml in the cache, warnings)`` for an importable file, converting it when not cached."""
    from illumix.scene.spectra import SceneError
    from illumix.scene_import import import_scene

    p = Path(path)
    if not p.is_file():
        raise SceneError(f"scene file {str(p)!r} {'is a directory' if p.is_dir() else 'does not exist'}")
    if rules is not None and not Path(rules).is_file():
        raise SceneError(f"rule file {str(rules)!r} does not exist")
    out = _cache_dir(p, _key(p, None if rules is None else Path(rules)))
    if (out / "scene.yaml").is_file() and (out / "warnings.json").is_file():
        return out / "scene.yaml", json.loads((out / "warnings.json").read_text())
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        doc, warns = import_scene(p, tmp, rules, assets="assets")
        write_yaml(doc, tmp / "scene.yaml")
        (tmp / "warnings.json").write_text(json.dumps(warns))
        try:
            tmp.rename(out)
        except OSError:  # another process got there first (its copy is as good) or a stale one
            if not (out / "warnings.json").is_file():
                shutil.rmtree(out, ignore_errors=True)
                tmp.rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out / "scene.yaml", warns


def write_yaml(doc: dict, path: Path, first_line: str | None = None) -> None:
    """Write a scene document as YAML (JSON for a ``.json`` path) through a temporary file in the same
    folder and a rename: never half a file. ``first_line``: a ``#`` comment line put first (YAML)."""
    import yaml

    if path.suffix.lower() == ".json":
        text = json.dumps(doc, indent=1)
    else:
        text = yaml.safe_dump(doc, sort_keys=False, allow_unicode=True, width=120)
        text = f"{first_line}\n{text}" if first_line else text
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def load_scene_file(path: str | Path, rules: str | Path | None = None) -> list:
    """The :class:`~scene.model.Scene` s of a scene file: ``.yaml``/``.yml``/``.json`` via
    :func:`scene.load.load_scenes`; the importable ones by their importer (:data:`scene_import.IMPORTERS`:
    ``.blend`` through Blender, ``.gltf``/``.glb``/``.obj``/``.xml`` converted into the cache of the
    module docstring, each import warning re-issued as a ``UserWarning``). ``rules`` applies to the
    converted files only."""
    from illumix.scene.load import load_scenes
    from illumix.scene.spectra import SceneError
    from illumix.scene_import import IMPORTERS, SUPPORTED

    p = Path(path)
    ext = p.suffix.lower()
    if ext not in IMPORTERS and ext not in NATIVE and p.is_file():  # (load_scenes words a missing file or a folder)
        raise SceneError(f"{p}: cannot read {p.suffix or 'a file without extension'!r} scenes; give "
                         f"{', '.join(NATIVE)} (illumix scene files) or {', '.join(IMPORTERS)} (imported)")
    if ext not in SUPPORTED:
        if rules is not None:
            raise SceneError(f"--rules applies to imported files ({', '.join(SUPPORTED)}), not {p.suffix!r}")
        if ext == ".blend":
            from illumix.scene_import.blend import load_blend

            return load_blend(p)
        return load_scenes(p)
    yaml_path, warns = import_cached(p, rules)
    for w in warns:
        warnings.warn(f"{p.name}: {w}", UserWarning, stacklevel=2)
    return load_scenes(yaml_path)
