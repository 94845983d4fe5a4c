"""Mitsuba XML, the files: parse a scene, inline its ``<include>`` files, collect ``<path>`` search
folders and upgrade legacy (0.5/2.x) files (:mod:`scene_import.mitsuba_legacy`), giving one element
tree for :mod:`scene_import.mitsuba_xml`.

- ``<include filename="…"/>``: the file's ``<scene>`` children replace the element, where it stands.
  Its name is looked up relative to the including file's folder, then the ``<path>`` folders, then
  the main file's folder (Mitsuba's file resolver, which has the scene's folder and the ``<path>``
  entries). Includes nest; a file including itself, directly or not, is an error naming the chain.
- ``<path value="…"/>``: a search folder for every file the scene names (relative to the file that
  declares it).
- Every element remembers the folder of the file it came from (attribute :data:`DIR_ATTR`), so a
  mesh or texture named in an included file is found beside that file first (:func:`resolve`).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from illumix.scene.spectra import SceneError
from illumix.scene_import.mitsuba_legacy import upgrade

DIR_ATTR = "__illumix_dir"  # set on every element: the folder of the file it was read from
MAX_DEPTH = 32  # nested includes deeper than this are surely a mistake


def _parse(path: Path, chain: list[Path], warn) -> ET.Element:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        where = f" (included from {chain[-1].name})" if chain else ""
        raise SceneError(f"{path}: not a readable XML file{where} ({exc})") from None
    if root.tag != "scene":
        raise SceneError(f"{path}: the root element is <{root.tag}>, not a Mitsuba <scene>")
    upgrade(root, path, warn)
    for el in root.iter():
        el.set(DIR_ATTR, str(path.parent))
    return root


def load_tree(path: Path, warn) -> tuple[ET.Element, list[Path]]:
    """``(root <scene> with every include inlined, search folders from <path>)``."""
    paths: list[Path] = []
    root = _parse(path, [], warn)
    _expand(root, [path.resolve()], path.parent, paths, warn)
    return root, paths


def _expand(parent: ET.Element, chain: list[Path], main_dir: Path, paths: list[Path], warn) -> None:
    """Replace ``<include>`` children of ``parent`` (recursively) by the included files' elements."""
    out: list[ET.Element] = []
    for el in list(parent):
        if el.tag == "path":
            p = Path(el.get("value", ""))
            paths.append(p if p.is_absolute() else Path(el.get(DIR_ATTR, main_dir)) / p)
            continue
        if el.tag != "include":
            _expand(el, chain, main_dir, paths, warn)
            out.append(el)
            continue
        name = el.get("filename", "")
        if not name:
            raise SceneError(f"{chain[-1]}: <include> without a filename")
        src = resolve_name(name, Path(el.get(DIR_ATTR, main_dir)), paths, main_dir)
        if not src.is_file():
            raise SceneError(f"{chain[-1]}: <include filename={name!r}>: no such file (looked in "
                             f"{', '.join(dict.fromkeys(str(c) for c in _candidates(Path(el.get(DIR_ATTR, main_dir)), paths, main_dir)))})")
        if src.resolve() in chain:
            loop = " -> ".join(p.name for p in [*chain, src.resolve()])
            raise SceneError(f"{chain[0]}: <include> cycle: {loop}; remove one of these includes")
        if len(chain) >= MAX_DEPTH:
            raise SceneError(f"{chain[0]}: includes nested deeper than {MAX_DEPTH}")
        sub = _parse(src, chain, warn)
        _expand(sub, [*chain, src.resolve()], main_dir, paths, warn)
        out.extend(c for c in sub if c.tag not in ("path", "include"))
    parent[:] = out


def _candidates(here: Path, paths: list[Path], main_dir: Path) -> list[Path]:
    return [here, *paths, main_dir]


def resolve_name(name: str, here: Path, paths: list[Path], main_dir: Path) -> Path:
    """The first existing ``folder / name`` among the file's own folder, ``<path>`` folders and the main
    file's folder (Windows ``\\`` separators accepted); the first candidate when none exists."""
    name = name.replace("\\", "/")
    p = Path(name)
    if p.is_absolute():
        return p
    cands = [c / p for c in _candidates(here, paths, main_dir)]
    return next((c for c in cands if c.exists()), cands[0])


def resolve(el: ET.Element, name: str, paths: list[Path], main_dir: Path) -> Path:
    """:func:`resolve_name` for a file named by (a child of) ``el``."""
    return resolve_name(name, Path(el.get(DIR_ATTR, main_dir)), paths, main_dir)
