"""Textures in Mitsuba: the scene model's :mod:`~scene.textures` as Mitsuba textures.

- A :class:`~scene.textures.PatternTexture` becomes ``illumix_pattern``, a texture
  written in Python over Dr.Jit (traced into the render's kernel like Mitsuba's own): a nearest-texel
  lookup of the label map, then for each sampled wavelength the band it falls in and the linear mix of
  the two neighbouring spectra's band averages — two gathers per wavelength. The map and the spectra
  table live in this process's registry under a content key (a scene dictionary carries only the key;
  every process that builds a scene dictionary fills its own registry first).
- A :class:`~scene.textures.BitmapTexture` becomes Mitsuba's ``bitmap`` (its spectral
  variants lift sRGB texels with the Jakob–Hanika 2019 model), repeated ``scale`` times per UV unit.
- A material's :class:`~scene.textures.NormalMap` becomes a raw ``bitmap`` inside Mitsuba's ``normalmap``
  BSDF, which wraps the material's own BSDF (inside ``twosided``).
"""

from __future__ import annotations

import hashlib

import numpy as np

from illumix.renderer_jobs.mitsuba.variant import RenderError, import_mitsuba
from illumix.scene.textures import BitmapTexture, NormalMap, PatternTexture

PLUGIN = "illumix_pattern"
_REGISTRY: dict[str, dict] = {}  # content key -> {"labels", "table", "start", "step", "scale"}
_REGISTERED: set[str] = set()  # variants the plugin is registered for


def _plugin_class(mi, dr):
    class PatternTex(mi.Texture):
        """A spectral label map (see module docstring); props: ``key`` into the registry."""

        def __init__(self, props):
            super().__init__(props)
            d = _REGISTRY[props["key"]]
            labels, table = d["labels"], d["table"]
            self.h, self.w = labels.shape
            self.k, self.nb = table.shape
            self.labels = mi.Float(labels.ravel())
            self.table = mi.Float(table.ravel())
            self.mean_value = float(table.mean(axis=1) @ np.bincount(
                np.clip(np.rint(labels).astype(int), 0, self.k - 1).ravel(), minlength=self.k) / labels.size)
            self.max_value = float(table.max())
            self.start, self.step = d["start"], d["step"]
            self.su, self.sv = d["scale"]

        def _label(self, si, active):
            u = si.uv.x * self.su
            v = si.uv.y * self.sv  # row 0 at v = 0, as Mitsuba's own bitmap texture
            x = dr.clip(mi.Int32(dr.floor((u - dr.floor(u)) * self.w)), 0, self.w - 1)
            y = dr.clip(mi.Int32(dr.floor((v - dr.floor(v)) * self.h)), 0, self.h - 1)
            t = dr.gather(mi.Float, self.labels, y * self.w + x, active)
            k0 = dr.clip(mi.Int32(dr.floor(t)), 0, self.k - 1)
            k1 = dr.minimum(k0 + 1, self.k - 1)
            return k0, k1, t - mi.Float(k0)

        def eval(self, si, active=True):
            k0, k1, f = self._label(si, active)
            out = mi.Spectrum(0.0)
            for i in range(4):
                b = dr.clip(mi.Int32(dr.floor((si.wavelengths[i] - self.start) / self.step)), 0, self.nb - 1)
                a0 = dr.gather(mi.Float, self.table, k0 * self.nb + b, active)
                a1 = dr.gather(mi.Float, self.table, k1 * self.nb + b, active)
                out[i] = a0 + f * (a1 - a0)
            return out

        def eval_1(self, si, active=True):
            return dr.mean(self.eval(si, active))

        def mean(self):
            return self.mean_value

        def max(self):
            return self.max_value

        def is_spatially_varying(self):
            return True

        def to_string(self):
            return f"PatternTex[{self.w}x{self.h}, {self.k} spectra]"

    return PatternTex


def _register(mi, dr) -> None:
    variant = mi.variant()
    if variant in _REGISTERED:
        return
    if not variant.startswith(("llvm", "cuda")):
        raise RenderError(f"pattern textures need a vectorised Mitsuba variant (llvm_ad_spectral or "
                          f"cuda_ad_spectral), not {variant}; on Debian: apt-get install libllvm19")
    cls = _plugin_class(mi, dr)
    mi.register_texture(PLUGIN, lambda props: cls(props))
    _REGISTERED.add(variant)


def pattern_texture_dict(scene, tex: PatternTexture, what: str) -> dict:
    """The Mitsuba texture dictionary of a pattern texture (registers the plugin and its data)."""
    mi, dr = import_mitsuba()
    _register(mi, dr)
    labels = tex.label_map()
    table = scene.texture_spectra(tex, what).astype(np.float32)
    grid = scene.spectral_grid
    key = hashlib.sha256(labels.tobytes() + table.tobytes() + repr(
        (float(grid.edges[0]), float(grid.step), tex.scale)).encode()).hexdigest()[:24]
    if key not in _REGISTRY:
        _REGISTRY[key] = {"labels": labels, "table": table, "start": float(grid.edges[0]),
                          "step": float(grid.step), "scale": tuple(float(s) for s in tex.scale)}
    return {"type": PLUGIN, "key": key}


def bitmap_texture_dict(scene, tex: BitmapTexture) -> dict:
    """Mitsuba's ``bitmap`` of an sRGB image (Jakob–Hanika upsampling), repeated ``scale`` times."""
    mi, _ = import_mitsuba()
    return {"type": "bitmap", "filename": str(scene.resolve_path(tex.file)), "raw": False,
            "filter_type": "bilinear", "wrap_mode": "repeat",
            "to_uv": mi.ScalarTransform4f().scale([tex.scale[0], tex.scale[1], 1.0])}


def normal_map_dict(scene, nm: NormalMap) -> dict:
    """Mitsuba's ``bitmap`` of a tangent-space normal map, read raw (its texels are vectors, not colours),
    for the ``normalmap`` BSDF that wraps a material with a ``normal_map``."""
    mi, _ = import_mitsuba()
    return {"type": "bitmap", "filename": str(scene.resolve_path(nm.file)), "raw": True,
            "filter_type": "bilinear", "wrap_mode": "repeat",
            "to_uv": mi.ScalarTransform4f().scale([nm.scale[0], nm.scale[1], 1.0])}


def reflectance_dict(scene, spec, what: str, step_spectrum) -> dict:
    """A material's ``reflectance`` — spectrum or texture — as a Mitsuba texture/spectrum dictionary."""
    if isinstance(spec, PatternTexture):
        return pattern_texture_dict(scene, spec, what)
    if isinstance(spec, BitmapTexture):
        return bitmap_texture_dict(scene, spec)
    return step_spectrum(scene.spectrum(spec, what), scene)
