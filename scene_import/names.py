"""Renderer-safe names for everything an importer brings in (shapes, lights, materials, views, groups).

Source files name things freely: Blender's duplicates are ``Cube.001``, glTF exported from Blender
keeps those, Mitsuba ids and OBJ groups contain dots, spaces, slashes. Scene names must match
``^[A-Za-z0-9][A-Za-z0-9_+-]*$`` here — stricter than the schema's :data:`scene.spectra.NAME_PATTERN`
because shape and light names become Mitsuba object keys, where ``.`` separates an object path
("object key … contains a '.'" at render time). :class:`Names` hands out unique keys per kind and
remembers every original it changed, which the builder records in the scene's ``generator.renamed``.
"""

from __future__ import annotations

import re

MAX_LEN = 100  # the schema's name length limit


def key_name(name: str, fallback: str = "unnamed") -> str:
    """``name`` as a renderer-safe key: runs of other characters (``.``, spaces, ``/`` …) become one
    ``_``, leading punctuation is dropped, at most :data:`MAX_LEN` characters; ``fallback`` when
    nothing is left. ``key_name("Cube.001") == "Cube_001"``."""
    s = re.sub(r"[^A-Za-z0-9_+\-]+", "_", str(name))
    s = re.sub(r"^[^A-Za-z0-9]+", "", s)[:MAX_LEN]
    return s or fallback


class Names:
    """Unique keys within one kind; ``renamed`` maps each changed original name to its key."""

    def __init__(self) -> None:
        self.used: set[str] = set()
        self.renamed: dict[str, str] = {}

    def __call__(self, name: str, fallback: str = "unnamed") -> str:
        base = key_name(name, fallback)
        out, k = base, 2
        while out in self.used:  # a collision (e.g. "Cube.001" next to a real "Cube_001"): numbered
            out, k = f"{base[:MAX_LEN - 5]}-{k}", k + 1
        self.used.add(out)
        if name and out != name:
            self.renamed.setdefault(str(name), out)
        return out


def renamed_summary(kinds: dict[str, Names], limit: int = 4000) -> tuple[str, int]:
    """``("kind: 'orig' -> key; …", count)`` of every renamed name (cut to ``limit`` characters)."""
    items = [f"{kind}: {orig!r} -> {key}" for kind, n in kinds.items() for orig, key in n.renamed.items()]
    text = "; ".join(items)
    if len(text) > limit:
        text = text[:limit].rsplit(";", 1)[0] + f"; … ({len(items)} in all)"
    return text, len(items)
