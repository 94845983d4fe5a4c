"""Mitsuba 3 XML, the values: ``$variables``, references, typed properties (``float``, ``rgb``, ``point``…),
spectra sampled as ``λ:v`` pairs or ``.spd`` files, named IORs, and transforms (:mod:`scene_import.mitsuba_xml`
maps the plugins).

Transforms follow Mitsuba: each operation inside ``<transform>`` left-multiplies the matrix so far
(``scale`` then ``rotate`` then ``translate`` reads top to bottom); ``rotate`` angles are degrees;
``lookat`` gives a camera frame with +z towards the target, +y up and +x to the left.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from illumix.scene.schema import SceneError
from illumix.scene_import.builder import SceneBuilder

IOR = {"vacuum": 1.0, "helium": 1.00004, "hydrogen": 1.00013, "air": 1.00028, "carbon dioxide": 1.00045,
       "water": 1.333, "acetone": 1.36, "ethanol": 1.361, "carbon tetrachloride": 1.461, "glycerol": 1.4729,
       "benzene": 1.501, "silicone oil": 1.52045, "bromine": 1.661, "water ice": 1.31, "fused quartz": 1.458,
       "pyrex": 1.47, "acrylic glass": 1.49, "polypropylene": 1.49, "bk7": 1.5046, "sodium chloride": 1.544,
       "amber": 1.55, "pet": 1.575, "diamond": 2.419}

class XmlDoc:
    """The scene tree (includes inlined) with its variables, ids and search folders."""

    def __init__(self, root: ET.Element, path: Path, b: SceneBuilder, paths: list[Path] | None = None) -> None:
        self.path, self.b, self.paths = path, b, list(paths or [])
        self.vars: dict[str, str] = {}
        self.ids: dict[str, ET.Element] = {}
        self.textures: dict[int, str] = {}
        for el in root:
            if el.tag == "default":
                self.vars.setdefault(el.get("name", ""), el.get("value", ""))
        for el in root.iter():
            if el.get("id") and el.tag != "ref":
                self.ids[self.sub(el.get("id"))] = el

    def sub(self, text: str | None) -> str:
        """``$name`` / ``${name}`` replaced by ``<default>`` values (unknown ones: an error)."""
        def repl(m: re.Match) -> str:
            k = m.group(1) or m.group(2)
            if k not in self.vars:
                raise SceneError(f"{self.path}: variable ${k} has no <default>; give one")
            return self.vars[k]
        return re.sub(r"\$\{(\w+)\}|\$(\w+)", repl, text or "")

    def get(self, el: ET.Element, attr: str, default: str | None = None) -> str | None:
        v = el.get(attr)
        return default if v is None else self.sub(v)

    def child(self, el: ET.Element, name: str) -> ET.Element | None:
        for c in el:
            if self.get(c, "name") == name:
                return self.ids.get(self.get(c, "id"), c) if c.tag == "ref" else c
        return None

    def value(self, el: ET.Element, name: str, default=None):
        c = self.child(el, name)
        if c is None:
            return default
        v = self.get(c, "value")
        if c.tag in ("float", "integer"):
            return float(v)
        if c.tag == "boolean":
            return v.lower() == "true"
        if c.tag in ("point", "vector"):
            return vec(self, c)
        return v

    def file(self, el: ET.Element, name: str) -> Path:
        """A file named in (a child of) ``el``: beside the file ``el`` came from, in a ``<path>`` folder,
        or beside the main file (:func:`scene_import.mitsuba_files.resolve`)."""
        from illumix.scene_import.mitsuba_files import resolve

        return resolve(el, self.sub(name), self.paths, self.path.parent)

    def deref(self, el: ET.Element) -> ET.Element:
        if el.tag == "ref":
            ref = self.get(el, "id")
            if ref not in self.ids:
                raise SceneError(f"{self.path}: <ref id={ref!r}> names no object")
            return self.ids[ref]
        return el


def vec(d: XmlDoc, el: ET.Element) -> np.ndarray:
    if el.get("value") is not None:
        parts = [float(x) for x in re.split(r"[,\s]+", d.get(el, "value").strip()) if x]
        return np.asarray(parts * 3 if len(parts) == 1 else parts, float)
    return np.array([float(d.get(el, k, "0")) for k in "xyz"])


def transform(d: XmlDoc, el: ET.Element | None) -> np.ndarray:
    """The 4×4 matrix of a ``<transform>`` element (identity for None)."""
    m = np.eye(4)
    if el is None:
        return m
    from illumix.scene.schema import rotation_matrix

    for op in el:
        t = np.eye(4)
        if op.tag == "matrix":
            t = np.asarray([float(x) for x in re.split(r"[,\s]+", d.get(op, "value").strip()) if x]).reshape(4, 4)
        elif op.tag == "translate":
            t[:3, 3] = vec(d, op) if op.get("value") else [float(d.get(op, k, "0")) for k in "xyz"]
        elif op.tag == "scale":
            s = vec(d, op) if op.get("value") else [float(d.get(op, k, "1")) for k in "xyz"]
            t = np.diag([*s, 1.0])
        elif op.tag == "rotate":
            axis = vec(d, op) if op.get("value") else [float(d.get(op, k, "0")) for k in "xyz"]
            t = rotation_matrix(tuple(axis), float(d.get(op, "angle", "0")))
        elif op.tag == "lookat":
            o, tg = vec(d, ET.Element("p", value=d.get(op, "origin"))), vec(d, ET.Element("p", value=d.get(op, "target")))
            up = vec(d, ET.Element("p", value=d.get(op, "up", "0, 1, 0")))
            if np.linalg.norm(tg - o) < 1e-12:
                raise ValueError(f"<lookat> with origin = target ({d.get(op, 'origin')}): no view direction")
            f = (tg - o) / np.linalg.norm(tg - o)
            left = np.cross(up, f)
            if np.linalg.norm(left) < 1e-9:  # looking along its up (a top-down camera with up +y)
                up = np.array([0.0, 0.0, -1.0]) if abs(f[1]) > 0.9 else np.array([0.0, 1.0, 0.0])
                d.b.warn(f"{d.path.name}: <lookat> up is parallel to its view direction; used up {up.tolist()}")
                left = np.cross(up, f)
            left /= np.linalg.norm(left)
            t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = left, np.cross(f, left), f, o
        else:
            d.b.warn(f"{d.path.name}: transform operation <{op.tag}> is not supported; ignored")
        m = t @ m
    return m


def to_world(d: XmlDoc, el: ET.Element) -> np.ndarray:
    t = next((c for c in el if c.tag == "transform" and d.get(c, "name") == "to_world"), None)
    return transform(d, t)


def spectrum_samples(d: XmlDoc, c: ET.Element) -> tuple[np.ndarray | None, np.ndarray]:
    if c.get("filename"):
        rows = [ln.split() for ln in d.file(c, d.get(c, "filename")).read_text().splitlines()
                if ln.strip() and not ln.lstrip().startswith("#")]
        a = np.asarray([[float(x) for x in r[:2]] for r in rows])
        return a[:, 0], a[:, 1]
    text = d.get(c, "value").strip()
    if ":" not in text:
        return None, np.array([float(text)])
    pairs = [p.split(":") for p in re.split(r"[,\s]+", text) if p]
    a = np.asarray([[float(w), float(v)] for w, v in pairs])
    return a[:, 0], a[:, 1]


def ior(d: XmlDoc, el: ET.Element, name: str, default: float) -> float:
    v = d.value(el, name)
    if v is None:
        return default
    try:
        return float(v)
    except ValueError:
        if str(v).lower() in IOR:
            return IOR[str(v).lower()]
        d.b.warn(f"{name} {v!r} is not a known IOR name; {default} used")
        return default
