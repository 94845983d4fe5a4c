"""Mitsuba XML, the emitters: ``point``, ``spot``, ``directional``, ``constant``, ``envmap`` lights and
the emission of ``area`` emitters (:func:`emission`), their spectra kept as faithfully as the scene
format allows (the group's spectrum is then chosen by :mod:`scene_import.grouping`):

- ``<spectrum value="λ:v, …"/>`` or ``filename`` → an exact table spectrum (zero outside its samples,
  as Mitsuba); strength = its luminance ``Y`` relative to the flat unit spectrum;
- ``<spectrum type="blackbody">`` (and legacy ``<blackbody>``) → ``blackbody:K``; strength = the ``Y``
  of Planck's radiance in W/(m²·sr·nm), which is what Mitsuba 3 emits (× a legacy ``scale``);
- ``<rgb>`` → its chromaticity and ``Y``; white is D65 exactly (Mitsuba's spectral RGB emission is
  D65-based), any other colour is approximated by an illuminant with a warning naming the light;
- ``<float>`` → D65 × ``v`` (Mitsuba multiplies a float emission by its D65); ``<spectrum value="v">``
  → the equal-energy illuminant ``E`` × ``v`` (Mitsuba's uniform spectrum; both checked in Mitsuba 3.9).
- ``envmap``: the map is copied; its group is rendered ``flat`` so that the map keeps its own colours.
"""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from illumix.scene_import.colour_match import blackbody_light, illuminant_xy, rgb_light, table_light
from illumix.scene_import.mitsuba_xml_values import XmlDoc, spectrum_samples, to_world, vec


@dataclass
class Emission:
    xy: np.ndarray | None  # chromaticity (None: black)
    y: float  # luminance relative to the flat unit spectrum: the emitter's strength
    spec: dict | str | None = None  # an exact spectrum for the group (table or "blackbody:K")
    given: str = ""  # how the file gave it, for warnings


def _white(v: float, given: str) -> Emission:
    return Emission(rgb_light([1, 1, 1])[0] if v > 0 else None, float(v), None, given)


def emission(d: XmlDoc, c: ET.Element | None, what: str) -> Emission:
    """The :class:`Emission` of an emission value element (rgb / spectrum / float)."""
    if c is None:
        return _white(1.0, "default white")
    c = d.deref(c)
    if c.tag == "rgb":
        rgb = vec(d, c)
        xy, y = rgb_light(rgb)
        return Emission(xy, y, None, f"rgb {np.round(rgb, 4).tolist()}")
    if c.tag == "float":
        v = float(d.get(c, "value"))
        return _white(v, f"float {v:g}")
    if c.tag == "spectrum":
        if d.get(c, "type") == "blackbody":
            t = float(d.value(c, "temperature", 6504.0))
            name, xy, y = blackbody_light(t)
            return Emission(xy, y * float(d.get(c, "scale", "1")), name, f"blackbody {t:g} K")
        wl, v = spectrum_samples(d, c)
        if wl is None:  # Mitsuba: a uniform (equal-energy) spectrum, unlike <float>, which is D65-based
            return Emission(np.asarray(illuminant_xy("E")) if v[0] > 0 else None, float(v[0]), "E",
                            f"uniform spectrum {float(v[0]):g}")
        spec, xy, y = table_light(wl, v)
        return Emission(xy, y, spec, f"spectrum of {len(wl)} samples, {wl.min():g}–{wl.max():g} nm")
    d.b.warn(f"{what}: emission given as <{c.tag}> (a texture?) is not supported; white of radiance 1 used")
    return _white(1.0, f"<{c.tag}> replaced by white")


def add_emitter(d: XmlDoc, el: ET.Element, name: str, parent: np.ndarray) -> None:
    """Add a top-level ``<emitter>`` as a light (unsupported types: a warning)."""
    t = d.get(el, "type")
    b = d.b
    what = f"emitter {name!r}"
    m = parent @ to_world(d, el)
    field = {"point": "intensity", "spot": "intensity", "directional": "irradiance", "constant": "radiance"}
    if t in field:
        em = emission(d, d.child(el, field[t]), what)
        if em.xy is None or em.y <= 0:
            b.warn(f"{what}: emits nothing (black or zero); skipped")
            return
        doc = _light_doc(d, el, t, m)
        b.add_light(name, doc, em.xy, em.y, what=what, spectrum=em.spec, given=em.given)
    elif t == "envmap":
        src = d.file(el, d.value(el, "filename", "") or "")
        if not src.is_file():
            b.warn(f"{what}: environment map {src.name!r} does not exist; skipped")
            return
        path, rel = b.file_path(src.stem, src.suffix.lower())
        shutil.copyfile(src, path)
        doc = {"type": "envmap", "filename": rel}
        if not np.allclose(m, np.eye(4)):
            doc["transform"] = {"matrix": np.round(m, 12).tolist()}
        b.add_light(name, doc, rgb_light([1, 1, 1])[0], float(d.value(el, "scale", 1.0)), what=what,
                    given="environment map")
    else:
        b.warn(f"{what}: emitter type {t!r} is not supported; skipped")


def _light_doc(d: XmlDoc, el: ET.Element, t: str, m: np.ndarray) -> dict:
    if t == "point":
        pos = d.value(el, "position")
        return {"type": "point", "position": np.asarray(m[:3, 3] if pos is None else pos, float).tolist()}
    if t == "spot":
        cutoff = float(d.value(el, "cutoff_angle", 20.0))
        beam = float(d.value(el, "beam_width", cutoff * 3 / 4))
        pos, fwd = m[:3, 3], m[:3, 2] / np.linalg.norm(m[:3, 2])
        return {"type": "spot", "position": pos.tolist(), "target": (pos + fwd).tolist(),
                "cutoff_angle": min(cutoff, 89.9), "beam_width": min(beam, cutoff, 89.9)}
    if t == "directional":
        direction = d.value(el, "direction")
        direction = m[:3, 2] if direction is None else m[:3, :3] @ direction
        return {"type": "directional", "direction": np.asarray(direction, float).tolist()}
    return {"type": "constant"}
