"""Mitsuba XML, legacy files: a ``<scene version="…">`` older than 3 is upgraded in place to what
Mitsuba 3 reads, as Mitsuba 3's own parser does for old files, with one warning per kind of change.

Upgraded (0.4/0.5/0.6 and 2.x):

- parameter names from camelCase to snake_case: ``toWorld`` → ``to_world``, ``maxDepth`` →
  ``max_depth``, ``intIOR`` → ``int_ior``, ``shapeIndex`` → ``shape_index`` … (2.x names already are);
- ``<lookAt>`` → ``<lookat>``;
- ``<srgb>`` (gamma-encoded sRGB, also ``#rrggbb``) → linear ``<rgb>``; a ``#rrggbb`` ``<rgb>`` likewise;
- ``<blackbody temperature="3000K" scale="s"/>`` → ``<spectrum type="blackbody">`` with its temperature
  (``scale`` kept as the attribute ``scale``, which the importer applies);
- bitmap ``uscale``/``vscale`` → a ``to_uv`` scale.

Refused with one line: a version that is not a version number, versions before 0.4 (a different
format) and versions after 3.x.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from illumix.scene.spectra import SceneError


def version_of(root: ET.Element, path: Path) -> tuple[int, ...] | None:
    """The ``version`` attribute as integers (None when absent: read as Mitsuba 3)."""
    v = root.get("version")
    if v is None:
        return None
    if not re.fullmatch(r"\s*\d+(\.\d+){0,2}\s*", v):
        raise SceneError(f"{path}: <scene version={v!r}> is not a version number (e.g. 3.0.0)")
    return tuple(int(x) for x in v.strip().split("."))


def snake(name: str) -> str:
    """``toWorld`` → ``to_world``; ``intIOR`` → ``int_ior`` (the 0.5 → 2 renaming)."""
    name = name.replace("IOR", "Ior")
    return re.sub(r"(?<=[a-z0-9])([A-Z])", lambda m: "_" + m.group(1).lower(), name)


def _srgb_linear(text: str) -> str:
    """An sRGB-encoded colour (``#rrggbb`` or floats) as linear floats (IEC 61966-2-1)."""
    t = text.strip()
    if t.startswith("#"):
        v = np.array([int(t[i:i + 2], 16) for i in (1, 3, 5)], float) / 255.0
    else:
        v = np.array([float(x) for x in re.split(r"[,\s]+", t) if x], float)
        v = np.repeat(v, 3) if v.size == 1 else v
    lin = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    return ", ".join(f"{x:.6g}" for x in lin)


def upgrade(root: ET.Element, path: Path, warn) -> None:
    """Upgrade ``root`` in place when its version is below 3 (module docstring)."""
    ver = version_of(root, path)
    if ver is None or ver[0] == 3:
        return
    label = ".".join(map(str, ver))
    if ver[0] > 3:
        raise SceneError(f"{path}: Mitsuba {label} files are newer than this importer (Mitsuba 3); "
                         "save the scene as a version 3 file")
    if ver < (0, 4):
        raise SceneError(f"{path}: Mitsuba {label} files cannot be upgraded (versions before 0.4 use "
                         "another format); re-save it with Mitsuba 0.5/0.6 or 3")
    seen: dict[str, list[str]] = {}
    for el in root.iter():
        _one(el, seen)
    root.set("version", "3.0.0")
    for kind, examples in seen.items():
        kinds = list(dict.fromkeys(examples))
        ex = ", ".join(kinds[:6]) + (f", … ({len(kinds)} different)" if len(kinds) > 6 else "")
        warn(f"{path.name}: legacy Mitsuba {label} file: {len(examples)} {kind} upgraded ({ex})")


def _one(el: ET.Element, seen: dict[str, list[str]]) -> None:
    if el.tag == "lookAt":
        el.tag = "lookat"
        seen.setdefault("<lookAt> transform(s)", []).append("<lookAt> → <lookat>")
    n = el.get("name")
    if n is not None and el.tag != "default" and snake(n) != n:
        el.set("name", snake(n))
        seen.setdefault("camelCase parameter name(s)", []).append(f"{n} → {snake(n)}")
    if el.tag == "srgb" or (el.tag == "rgb" and (el.get("value") or "").strip().startswith("#")):
        el.set("value", _srgb_linear(el.get("value", "0")))
        seen.setdefault("sRGB-encoded colour(s)", []).append(f"<{el.tag}> → linear <rgb>")
        el.tag = "rgb"
    if el.tag == "blackbody":
        t = (el.get("temperature") or "6504").strip().lower().removesuffix("k")
        el.tag = "spectrum"
        el.attrib.pop("temperature", None)
        el.set("type", "blackbody")
        el.append(ET.Element("float", name="temperature", value=t))
        seen.setdefault("<blackbody> element(s)", []).append(f"<blackbody {t} K> → <spectrum type=blackbody>")
    if el.tag == "texture" and el.get("type") == "bitmap":
        sc = {c.get("name"): c for c in el if c.get("name") in ("uscale", "vscale")}
        if sc:
            u, v = (float(sc[k].get("value", "1")) if k in sc else 1.0 for k in ("uscale", "vscale"))
            for c in sc.values():
                el.remove(c)
            tr = ET.SubElement(el, "transform", name="to_uv")
            ET.SubElement(tr, "scale", x=f"{u:g}", y=f"{v:g}")
            seen.setdefault("bitmap uscale/vscale", []).append(f"scale {u:g}×{v:g} → to_uv")
