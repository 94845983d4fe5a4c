"""Scene documents of older format versions, brought up to the current one before validation.

A document says which format it is written in with ``schema_version`` (an integer). Loading
(:func:`scene.load.scene_from_dict`) calls :func:`migrate` first:

- a version newer than :data:`CURRENT` (or not a positive integer) is refused with one line naming
  the versions this illumix reads (:data:`SUPPORTED`);
- an older version is upgraded step by step through :data:`MIGRATIONS` (``{from_version: step}``,
  each step a pure function of the parsed document returning the next version's document and a note
  per change), and each change is reported as a warning;
- a document without ``schema_version`` is read as version 1: that was the field's default before
  versions were checked, so every file written then omits it (and importers' documents too).

History (``git log -- scene/ renderer_jobs/scene*.py``)
-------------------------------------------------------
Version 1 grew additively and every such file still reads unchanged: portal emitters
(``emitter.portal``, cfd20b1), spectral textures (224d700), ``generator`` (224d700), the rule that a
sphere scales uniformly (3c5681e, a refusal: such files never rendered what they described),
``light_groups[].kind`` (56704eb), material ``normal_map``. Version 2 is the first change a version-1
file can fail: **shape and light names may not contain '.'** — they are the renderer's object keys
(Mitsuba reads ``a.b`` as an object path), so a Blender duplicate ``Cube.001`` passed validation in
version 1 and then failed to render. The 1 → 2 step renames them (``.`` → ``_``, numbered on a clash);
nothing refers to a shape or light by name, so no other field changes and the cubes are the same.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

#: The format version this illumix writes (:attr:`scene.model.Scene.schema_version`).
CURRENT = 2
#: The read version of a document without ``schema_version`` (module docstring).
UNVERSIONED = 1

Step = Callable[[dict], tuple[dict, list[str]]]


def _key(name: str, used: set[str]) -> str:
    """``name`` with each run of ``.`` as one ``_`` (``Cube.001`` → ``Cube_001``), unique in ``used``."""
    base = re.sub(r"\.+", "_", name).strip("_") or "unnamed"
    out, k = base, 2
    while out in used:  # "Cube.001" beside a real "Cube_001"
        out, k = f"{base}-{k}", k + 1
    return out


def _v1_to_v2(doc: dict) -> tuple[dict, list[str]]:
    """Version 1 → 2: shape and light names without '.' (module docstring)."""
    out = dict(doc)
    notes: list[str] = []
    for kind in ("shapes", "lights"):
        items = doc.get(kind)
        if not isinstance(items, list):
            continue
        used = {it.get("name") for it in items if isinstance(it, dict) and isinstance(it.get("name"), str)
                and "." not in it["name"]}
        renamed, new_items = [], []
        for it in items:
            name = it.get("name") if isinstance(it, dict) else None
            if isinstance(name, str) and "." in name:
                new = _key(name, used)
                used.add(new)
                renamed.append((name, new))
                it = dict(it, name=new)
            new_items.append(it)
        out[kind] = new_items
        if renamed:
            shown = ", ".join(f"{a!r} -> {b!r}" for a, b in renamed[:5]) + (" …" if len(renamed) > 5 else "")
            notes.append(f"{kind}: {len(renamed)} name(s) with '.' renamed ({shown}); since scene format 2 "
                         "shape and light names are renderer keys without '.'")
    return out, notes


#: ``{version: the step from it to version + 1}``; one entry per version below :data:`CURRENT`.
MIGRATIONS: dict[int, Step] = {1: _v1_to_v2}
#: Every version this illumix reads (older ones are migrated).
SUPPORTED: tuple[int, ...] = (*sorted(MIGRATIONS), CURRENT)


def document_version(doc: dict, source: str = "scene") -> int:
    """The document's ``schema_version`` (:data:`UNVERSIONED` when absent); ``ValueError`` (one line,
    naming the supported versions) for a newer, non-integer or non-positive one."""
    v = doc.get("schema_version", UNVERSIONED)
    supported = ", ".join(map(str, SUPPORTED))
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ValueError(f"{source}: schema_version {v!r} is not a format version; this illumix reads versions "
                         f"{supported} (write schema_version: {CURRENT})")
    if v > CURRENT:
        raise ValueError(f"{source}: schema_version {v} is newer than this illumix reads (versions {supported}); "
                         "upgrade illumix, or write the scene in a supported version")
    return v


def migrate(doc: Any, source: str = "scene") -> tuple[Any, list[str]]:
    """``(document at CURRENT, notes)``: ``doc`` upgraded through :data:`MIGRATIONS` (not modified in
    place); a non-mapping is returned as is (validation refuses it). ``ValueError`` for a version this
    illumix does not read."""
    if not isinstance(doc, dict):
        return doc, []
    v = document_version(doc, source)
    notes: list[str] = []
    while v < CURRENT:
        doc, step_notes = MIGRATIONS[v](doc)
        notes += [f"{source}: format {v} -> {v + 1}: {n}" for n in step_notes]
        v += 1
    return dict(doc, schema_version=CURRENT), notes
