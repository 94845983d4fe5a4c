"""Names, colours and materials of the ``.blend`` importer (:mod:`scene_import.blend`).

Scene-name sanitising, the Jakob & Hanika upsampling of linear sRGB colours to reflectance spectra,
``illumix_reflectance`` look-ups, the worker's material records as illumix materials (with their image
textures and normal maps, written beside the worker's output), and the flat group strength of an
emission colour. The conventions are the importer's: see its module docstring.
"""

from __future__ import annotations

import difflib
import os
import re
import warnings
from pathlib import Path

import numpy as np

from illumix.scene.schema import SceneError
from illumix.scene_import.colour_match import jakob_hanika

WAVELENGTHS = np.arange(380.0, 781.0, 5.0)  # nm, the upsampled spectra's table
GREY = 1e-3  # relative channel spread below which a colour counts as grey


# -- names ------------------------------------------------------------------------------------


def sanitize(name: str, fallback: str = "unnamed") -> str:
    """``name`` under the scene name rules ``^[A-Za-z0-9][A-Za-z0-9_.+-]*$`` (no ``..``, ≤ 100 chars):
    other characters become ``_``, leading punctuation is dropped."""
    s = re.sub(r"[^A-Za-z0-9_.+\-]+", "_", name)
    s = re.sub(r"\.{2,}", ".", s)
    s = re.sub(r"^[^A-Za-z0-9]+", "", s)[:100]
    return s or fallback


class _Names:
    """Unique sanitised names within one kind (shapes, lights, views, materials)."""

    def __init__(self) -> None:
        self.used: set[str] = set()

    def __call__(self, name: str, fallback: str = "unnamed") -> str:
        base = sanitize(name, fallback)
        out, k = base, 2
        while out in self.used:
            out, k = f"{base[:95]}-{k}", k + 1
        self.used.add(out)
        return out


# -- spectra ----------------------------------------------------------------------------------


def rgb_to_spectrum(rgb, what: str) -> dict:
    """An inline table reflectance (380–780 nm / 5 nm, values in [0, 1]) whose sRGB colour under D65
    is the linear sRGB ``rgb`` (Jakob & Hanika 2019). Components outside [0, 1] are clipped, with a
    warning, as is a colour the smooth spectra cannot reach (CIE ΔE2000 > 1)."""
    c = np.asarray(rgb, dtype=float)[:3]
    if np.any(c < 0) or np.any(c > 1):
        warnings.warn(f"{what}: base colour {np.round(c, 3).tolist()} is outside [0, 1]; clipped", UserWarning,
                      stacklevel=3)
        c = np.clip(c, 0.0, 1.0)
    values, err = jakob_hanika(tuple(round(float(x), 6) for x in c))
    if err > 1.0:
        warnings.warn(f"{what}: no reflectance spectrum reproduces base colour {np.round(c, 3).tolist()} "
                      f"closely (ΔE2000 {err:.1f}); used the closest smooth spectrum", UserWarning, stacklevel=3)
    return {"wavelengths": WAVELENGTHS.tolist(), "values": list(values)}


def resolve_reflectance(ref: str, what: str) -> dict:
    """``{"library", "sample"}`` for ``"Library/Sample"`` or a bare sample name (the first of
    :func:`retarget.reflectances.set_names` that holds it); :class:`SceneError` with close matches."""
    from illumix.retarget.reflectances import get_reflectances, set_names

    ref = ref.strip()
    libs = {lib: get_reflectances(lib)[0] for lib in set_names()}
    for lib, names in libs.items():
        if ref.startswith(lib + "/") and ref[len(lib) + 1:] in names:
            return {"library": lib, "sample": ref[len(lib) + 1:]}
    for exact in (True, False):
        for lib, names in libs.items():
            for n in names:
                if n == ref or (not exact and n.lower() == ref.lower()):
                    return {"library": lib, "sample": n}
    known = [f"{lib}/{n}" for lib, names in libs.items() for n in names]
    close = difflib.get_close_matches(ref, known + [n for names in libs.values() for n in names], n=3, cutoff=0.5)
    hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
    raise SceneError(f"{what}: illumix_reflectance {ref!r} is not a known reflectance{hint} "
                     f"(give 'Library/Sample'; libraries: {', '.join(libs)})")


# -- materials and emission ---------------------------------------------------------------------


def _warn(msg: str, up: int = 0) -> None:
    # ``up``: helper frames between the warning and scene_doc (or material_doc), so a warning is
    # attributed to the frame it was before scene_doc was split into helpers.
    warnings.warn(msg, UserWarning, stacklevel=4 + up)


def _is_grey(rgb) -> bool:
    c = np.asarray(rgb, dtype=float)[:3]
    return float(c.max() - c.min()) <= GREY * max(float(c.max()), 1e-12)


def material_doc(info: dict, what: str, base: Path | None = None) -> dict | None:
    """The illumix material for a worker material record (None: emission only); ``base``: the worker's
    output folder, where its image textures are (without it, a texture's mean colour is used)."""
    for p in info["problems"]:
        _warn(f"{what}: {p}")
    if info["shader"] == "emission":
        return None
    alpha = min(max(float(info["roughness"]) ** 2, 1e-3), 1.0)
    ior = min(max(float(info.get("ior", 1.5)), 1.0001), 4.0)
    ref = info.get("illumix_reflectance")
    if info["metallic"] > 0.5 or info["transmission"] > 0.5:
        if info.get("normal_map") and info["metallic"] <= 0.5:
            _warn(f"{what}: a dielectric takes no normal map; {info['normal_map']['image']!r} is not used")
        kind = "roughconductor (aluminium)" if info["metallic"] > 0.5 else f"dielectric (IOR {ior:.3g})"
        _warn(f"{what}: imported as {kind}; its base colour {'and illumix_reflectance are' if ref else 'is'} "
              "not used")
        if info["metallic"] > 0.5:
            return _with_normal_map({"kind": "roughconductor", "conductor": "Al", "alpha": alpha}, info, base)
        return {"kind": "dielectric", "int_ior": ior}
    plastic = info["shader"] == "principled" and info["roughness"] < 0.999
    tex = info.get("base_color_texture")
    if ref and tex:
        _warn(f"{what}: illumix_reflectance replaces the image texture {tex['image']!r}")
    if ref:
        refl = resolve_reflectance(ref, what)
    elif tex and base is not None:
        from illumix.scene.plastic_scale import plastic_diffuse_scale

        refl = _texture_file(tex, base, 1.0 / plastic_diffuse_scale(alpha, ior) if plastic else 1.0, what)
    elif plastic:
        # Mitsuba's roughplastic darkens its diffuse term by the coating's transmittances, Blender's
        # Principled BSDF does not: the base colour / c keeps the Blender look (the inverse of the
        # Cycles backend's mapping, scene.plastic_scale.plastic_diffuse_scale).
        from illumix.scene.plastic_scale import plastic_diffuse_scale

        base = np.asarray(info["base_color"], dtype=float)[:3] / plastic_diffuse_scale(alpha, ior)
        if np.any(base > 1):
            _warn(f"{what}: base colour / {plastic_diffuse_scale(alpha, ior):.3g} (to render as bright as "
                  "Blender's Principled BSDF as a rough plastic) exceeds 1; clipped")
        refl = rgb_to_spectrum(np.minimum(base, 1.0), what)
    else:
        refl = rgb_to_spectrum(info["base_color"], what)
    if plastic:
        doc = {"kind": "roughplastic", "reflectance": refl, "alpha": alpha, "int_ior": ior}
        return _with_normal_map(doc, info, base)
    return _with_normal_map({"kind": "diffuse", "reflectance": refl}, info, base)


def _with_normal_map(doc: dict, info: dict, base: Path | None) -> dict:
    """``doc`` with the material's normal map (its strength baked in, beside the worker's PNG), if any."""
    nm = info.get("normal_map")
    if not nm or base is None:
        return doc
    from PIL import Image

    from illumix.scene_import.gltf_textures import normal_png

    src = base / nm["file"]
    data, digest = normal_png(Image.open(src), 1.0, float(nm["strength"]))
    dst = src.with_name(f"{src.stem}-normal-{digest}.png")
    if not dst.is_file():
        tmp = dst.with_name(f".{dst.stem}.{os.getpid()}.png")
        tmp.write_bytes(data)
        os.replace(tmp, dst)
    return {**doc, "normal_map": {"file": str(dst)}}


def _texture_file(tex: dict, base: Path, factor: float, what: str) -> dict:
    """A bitmap reflectance: the worker's PNG × ``factor`` per texel (linear light; the plastic
    brightness correction), clipped only where it exceeds 1, written beside it (absolute path)."""
    from PIL import Image

    from illumix.scene_import.gltf_textures import with_factor

    src = base / tex["file"]
    dst = src.with_name(f"{src.stem}-x{factor:.5f}.png")
    img, over = with_factor(Image.open(src), np.full(3, factor))
    if over > 0:
        _warn(f"{what}: image {tex['image']!r} / {1 / factor:.3g} (to render as bright as Blender's Principled "
              f"BSDF as a rough plastic) exceeds 1 in {over:.1%} of the texels; clipped there", 1)
    if not dst.is_file():  # written once into the cache; a temporary name, then renamed (concurrent imports)
        tmp = dst.with_name(f".{dst.stem}.{os.getpid()}.png")
        img.save(tmp, format="PNG")
        os.replace(tmp, dst)
    return {"file": str(dst)}


def _emission(color, strength: float, what: str, up: int = 0) -> float:
    """Strength per unit of a flat group spectrum: ``strength × max(colour)``; warns if coloured
    (``up``: as for :func:`_warn`)."""
    c = np.asarray(color, dtype=float)[:3]
    s = float(strength) * float(c.max())
    if s > 0 and not _is_grey(c):
        _warn(f"{what}: emission colour {np.round(c, 3).tolist()} is replaced by the light group's "
              "emission spectrum (flat); only its strength × largest channel is kept", up)
    return s
