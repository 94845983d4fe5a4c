"""Mitsuba XML scenes (3, and legacy 0.5/2.x upgraded) → an illumix scene document, read with ElementTree.

Files, includes, search paths and legacy upgrades: :mod:`scene_import.mitsuba_files`. Values,
references and transforms: :mod:`scene_import.mitsuba_xml_values`. Supported: ``$variables`` with
``<default name value>``; ``<ref id>`` to top-level ``bsdf``/``texture`` objects; transforms (``matrix``,
``translate``, ``rotate``, ``scale``, ``lookat``, applied in order as Mitsuba does: each operation
left-multiplies the matrix so far).

- **Shapes** ``obj``/``ply`` (copied beside the scene), ``serialized`` (read by Mitsuba, written as
  PLY: :mod:`scene_import.mitsuba_meshes`), ``rectangle``, ``cube``, ``disk``, ``sphere`` (``center``,
  ``radius``), ``cylinder`` (``p0``, ``p1``, ``radius``), with ``to_world``.
- **BSDFs** ``diffuse``, ``roughplastic``, ``plastic`` (α 0.01), ``conductor`` (α 0.01) /
  ``roughconductor`` (``material`` if illumix knows it, else Al), ``dielectric`` (also ``thindielectric``
  / ``roughdielectric``, with a warning), a ``twosided`` wrapper (illumix ``two_sided``; Mitsuba's
  BSDFs are one-sided otherwise); wrappers ``bumpmap``/``normalmap``/``mask`` keep their inner BSDF
  (warning). Reflectances: ``<rgb>`` (linear) → Jakob–Hanika spectrum; ``<float>``/``<spectrum value="v">``
  → constant; ``<spectrum value="λ:v, …">`` or ``filename`` → a table; ``bitmap`` textures (PNG/JPEG,
  copied) → bitmap textures.
- **Emitters** ``area`` (in a shape), ``point``, ``spot``, ``directional``, ``constant`` and ``envmap``
  → lights, their spectra kept where the file gives one (:mod:`scene_import.mitsuba_emitters`).
- **Sensors** ``perspective`` (``thinlens`` with a warning) → views: ``to_world`` (Mitsuba's camera
  looks down its +z with +y up), ``fov`` + ``fov_axis`` or ``focal_length`` (35 mm film), film
  ``width``/``height`` (768×576 default).

Anything else (integrators other than ``path`` ``max_depth``, other plugins) is a warning naming the object.
"""

from __future__ import annotations

import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from illumix.scene.schema import CONDUCTORS
from illumix.scene_import.builder import SceneBuilder
from illumix.scene_import.colour_match import reflectance
from illumix.scene_import.mitsuba_emitters import add_emitter, emission
from illumix.scene_import.mitsuba_files import load_tree
from illumix.scene_import.mitsuba_meshes import MESHES, mesh_doc, object_points
from illumix.scene_import.mitsuba_xml_values import XmlDoc, ior, spectrum_samples, to_world, transform, vec

SHAPES = (*MESHES, "rectangle", "cube", "disk", "sphere", "cylinder")


def _reflectance(d: XmlDoc, c: ET.Element | None, what: str, default: float = 0.5):
    """A schema reflectance from a ``reflectance``-like child element."""
    if c is None:
        return {"value": default}
    c = d.deref(c)
    if c.tag == "rgb":
        return reflectance(vec(d, c), what, d.b.warn)
    if c.tag == "float":
        return {"value": float(d.get(c, "value"))}
    if c.tag == "spectrum":
        if d.get(c, "type") == "blackbody":
            d.b.warn(f"{what}: a blackbody reflectance makes no sense; grey 0.5 used")
            return {"value": 0.5}
        wl, v = spectrum_samples(d, c)
        return {"value": float(v[0])} if wl is None else {"wavelengths": wl.tolist(), "values": v.tolist()}
    if c.tag == "texture" and d.get(c, "type") == "bitmap":
        src = d.file(c, d.value(c, "filename", "") or "")
        if src.suffix.lower() not in (".png", ".jpg", ".jpeg") or not src.is_file():
            d.b.warn(f"{what}: bitmap {src.name!r} is not a readable PNG/JPEG; grey {default} used")
            return {"value": default}
        if d.value(c, "raw", False):
            d.b.warn(f"{what}: bitmap {src.name!r} has raw=true; it is read as sRGB")
        key = id(c)
        if key not in d.textures:
            path, rel = d.b.file_path(src.stem, src.suffix.lower())
            shutil.copyfile(src, path)
            d.textures[key] = rel
        out: dict = {"file": d.textures[key]}
        uv = next((t for t in c if t.tag == "transform" and d.get(t, "name") == "to_uv"), None)
        if uv is not None:
            m = transform(d, uv)
            if np.allclose(m[:3, :3], np.diag(np.diag(m[:3, :3]))) and np.allclose(m[:2, 3], 0):
                out["scale"] = [float(m[0, 0]), float(m[1, 1])]
            else:
                d.b.warn(f"{what}: bitmap to_uv other than a scale is ignored")
        return out
    d.b.warn(f"{what}: <{c.tag} type={d.get(c, 'type')!r}> is not supported as a reflectance; grey {default} used")
    return {"value": default}


def _bsdf(d: XmlDoc, el: ET.Element, what: str, two: bool = False) -> dict:
    t = d.get(el, "type")
    warn = d.b.warn
    if t == "twosided":
        inner = next((d.deref(c) for c in el if c.tag in ("bsdf", "ref")), None)
        return _bsdf(d, inner, what, True) if inner is not None else {"kind": "diffuse", "reflectance": {"value": 0.5}}
    if t in ("bumpmap", "normalmap", "mask"):
        warn(f"{what}: <bsdf type={t!r}> is ignored (its inner BSDF is used)")
        inner = next((d.deref(c) for c in el if c.tag in ("bsdf", "ref")), None)
        return _bsdf(d, inner, what, two) if inner is not None else {"kind": "diffuse", "reflectance": {"value": 0.5}}
    dist = d.value(el, "distribution", "beckmann")
    if t in ("roughplastic", "roughconductor") and dist != "ggx":
        warn(f"{what}: {dist} microfacets are rendered as GGX of the same alpha")
    alpha = float(d.value(el, "alpha", 0.1)) if t.startswith("rough") else 0.01
    if t in ("plastic", "conductor"):
        warn(f"{what}: smooth {t} is approximated as rough with alpha 0.01")
    alpha = min(max(alpha, 1e-3), 1.0)
    if t == "diffuse":
        return {"kind": "diffuse", "reflectance": _reflectance(d, d.child(el, "reflectance"), what), "two_sided": two}
    if t in ("plastic", "roughplastic"):
        return {"kind": "roughplastic", "reflectance": _reflectance(d, d.child(el, "diffuse_reflectance"), what),
                "alpha": alpha, "int_ior": min(max(ior(d, el, "int_ior", 1.49), 1.0001), 4.0),
                "ext_ior": min(max(ior(d, el, "ext_ior", 1.000277), 1.0), 4.0), "two_sided": two}
    if t in ("conductor", "roughconductor"):
        mat = d.value(el, "material", "none" if d.child(el, "eta") is None else None)
        if mat not in CONDUCTORS:
            warn(f"{what}: conductor {'given by eta/k' if mat is None else repr(mat)} is not in illumix's table; "
                 "aluminium (Al) used")
            mat = "Al"
        out = {"kind": "roughconductor", "conductor": mat, "alpha": alpha, "two_sided": two}
        sr = d.child(el, "specular_reflectance")
        if sr is not None:
            spec = _reflectance(d, sr, what, 1.0)
            if "file" in spec:
                warn(f"{what}: a textured specular_reflectance is not supported; 1 used")
            else:
                out["specular_reflectance"] = spec
        return out
    if t in ("dielectric", "thindielectric", "roughdielectric"):
        if t != "dielectric":
            warn(f"{what}: {t} is imported as a smooth dielectric")
        return {"kind": "dielectric", "int_ior": min(max(ior(d, el, "int_ior", 1.5046), 1.0001), 4.0),
                "ext_ior": min(max(ior(d, el, "ext_ior", 1.000277), 1.0), 4.0)}
    warn(f"{what}: <bsdf type={t!r}> is not supported; grey diffuse 0.5 used")
    return {"kind": "diffuse", "reflectance": {"value": 0.5}, "two_sided": two}


def import_mitsuba_xml(path: Path, b: SceneBuilder) -> str:
    """Fill ``b`` from a Mitsuba 3 XML file; returns the scene's name (module docstring)."""
    root, paths = load_tree(path, b.warn)
    d = XmlDoc(root, path, b, paths)
    mats: dict[int, str] = {}
    for i, el in enumerate(root):
        what = f"<{el.tag}{' type=' + repr(d.get(el, 'type')) if el.get('type') else ''}" \
               f"{' id=' + repr(d.get(el, 'id')) if el.get('id') else ''}>"
        if el.tag in ("default", "bsdf", "texture", "spectrum", "rgb"):
            continue
        if el.tag == "shape":
            _shape(d, el, i, mats)
        elif el.tag == "emitter":
            add_emitter(d, el, d.get(el, "id") or f"{d.get(el, 'type')}{i}", np.eye(4))
        elif el.tag == "sensor":
            _sensor(d, el, i)
        elif el.tag == "integrator":
            depth = d.value(el, "max_depth")
            if d.get(el, "type") not in ("path", "volpath", "direct"):
                b.warn(f"{what}: integrator is not used (illumix renders with its own path tracer)")
            if depth == -1:  # Mitsuba's "unlimited"
                b.max_depth = 64
                b.warn(f"{what}: max_depth -1 (unlimited) is rendered with illumix's largest, 64")
            elif depth is not None and 1 <= depth <= 64:
                b.max_depth = int(depth)
            elif depth is not None:
                b.warn(f"{what}: max_depth {depth:g} is outside 1..64; illumix's default 8 used")
        else:
            b.warn(f"{what}: not supported; ignored")
    return path.stem


def _shape(d: XmlDoc, el: ET.Element, i: int, mats: dict[int, str]) -> None:
    t = d.get(el, "type")
    name = d.get(el, "id") or d.get(el, "name") or f"{t}{i}"
    what = f"shape {name!r}"
    b = d.b
    if t not in SHAPES:
        b.warn(f"{what}: shape type {t!r} is not supported; skipped")
        return
    m = to_world(d, el)
    doc: dict = {"type": t}
    if t in MESHES:
        mesh = mesh_doc(d, el, t, name, what)
        if mesh is None:
            return
        doc = mesh
    elif t == "sphere":
        doc.update(center=list(d.value(el, "center", np.zeros(3))), radius=float(d.value(el, "radius", 1.0)))
    elif t == "cylinder":
        doc.update(p0=list(d.value(el, "p0", np.zeros(3))), p1=list(d.value(el, "p1", np.array([0, 0, 1.0]))),
                   radius=float(d.value(el, "radius", 1.0)))
    if d.value(el, "flip_normals", False):
        b.warn(f"{what}: flip_normals is ignored")
    if not np.allclose(m, np.eye(4)):
        doc["transform"] = {"matrix": np.round(m, 12).tolist()}
    pts = object_points(b, doc)
    b.extend_bounds(pts @ m[:3, :3].T + m[:3, 3])
    bsdf = next((d.deref(c) for c in el if c.tag in ("bsdf", "ref")), None)
    if bsdf is not None and bsdf.tag == "bsdf":
        if id(bsdf) not in mats:
            mname = d.get(bsdf, "id") or f"{name}-bsdf"
            mats[id(bsdf)] = b.add_material(mname, _bsdf(d, bsdf, f"bsdf {mname!r}"))
        doc["material"] = mats[id(bsdf)]
    em_el = next((c for c in el if c.tag == "emitter"), None)
    emitter = None
    if em_el is not None:
        if d.get(em_el, "type") != "area":
            b.warn(f"{what}: emitter type {d.get(em_el, 'type')!r} inside a shape is not supported; ignored")
        else:
            em = emission(d, d.child(em_el, "radiance"), what)
            if em.xy is not None and em.y > 0:
                if doc.get("material") and b.materials[doc["material"]]["kind"] == "dielectric":
                    b.warn(f"{what}: a dielectric cannot emit in illumix; its emission is dropped")
                else:
                    emitter = ([name, d.get(em_el, "id") or ""], name, em.xy, em.y)
    if "material" not in doc and emitter is None:
        # Mitsuba's default BSDF is a grey diffuse (reflectance 0.5), one-sided
        if "default-diffuse" not in b.materials:
            b.materials["default-diffuse"] = {"kind": "diffuse", "reflectance": {"value": 0.5}, "two_sided": False}
        doc["material"] = "default-diffuse"
    b.add_shape(name, doc, emitter, what=what, **({"spectrum": em.spec, "given": em.given} if emitter else {}))


def _sensor(d: XmlDoc, el: ET.Element, i: int) -> None:
    t = d.get(el, "type")
    name = d.get(el, "id") or f"sensor{i}"
    what = f"sensor {name!r}"
    if t not in ("perspective", "thinlens"):
        d.b.warn(f"{what}: sensor type {t!r} cannot be imported; skipped")
        return
    if t == "thinlens":
        d.b.warn(f"{what}: thin-lens depth of field is ignored (a pinhole camera)")
    film = next((c for c in el if c.tag == "film"), None)
    w = int(d.value(film, "width", 768)) if film is not None else 768
    h = int(d.value(film, "height", 576)) if film is not None else 576
    fov = d.value(el, "fov")
    axis = (d.value(el, "fov_axis", "x") or "x").lower()
    if fov is None:
        f = float(str(d.value(el, "focal_length", "50mm")).removesuffix("mm"))
        fov, axis = math.degrees(2 * math.atan(36.0 / (2 * f))), "x"
    t_half = math.tan(math.radians(float(fov)) / 2)
    if axis == "y" or (axis == "smaller" and h < w) or (axis == "larger" and h > w):
        t_half *= w / h
    elif axis == "diagonal":
        t_half *= w / math.hypot(w, h)
    m = to_world(d, el)
    if np.linalg.det(m[:3, :3]) < 0:
        d.b.warn(f"{what}: its to_world mirrors the image (e.g. scale x -1); the view is not mirrored")
    d.b.add_view(name, m[:3, 3], m[:3, 2], m[:3, 1], math.degrees(2 * math.atan(t_half)), (w, h))
