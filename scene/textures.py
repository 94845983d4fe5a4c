"""Scene description, textures: reflectances that vary over a surface.

Two kinds, both usable wherever a material takes a ``reflectance`` (``diffuse``, ``roughplastic``):

- :class:`PatternTexture` — a **spectral label map**: a procedural pattern (wood grain, fabric weave,
  tiles, stripes such as book spines, a checkerboard, blobs and pictures) whose texels hold a label
  ``t ∈ [0, K−1]`` mixing the texture's ``K`` measured spectra: integer ``t`` is spectrum ``t``,
  fractional ``t`` the linear mix of its two neighbours (wood grain shades continuously between
  early- and latewood). Every texel is a convex mix of band-averaged spectra, so the scene stays
  piecewise constant over each band and relighting stays exact (DESIGN.md "The key idea").
  Deterministic in ``seed``: the map is a function of the description alone.
- :class:`BitmapTexture` — an 8-bit sRGB image (PNG/JPEG) lifted to spectra texel by texel with the
  Jakob & Hanika (2019) sigmoid model, as Mitsuba's spectral variants do for any RGB texture. Smooth
  spectra, exact within each band up to the band average the renderer takes.

Textures render with the Mitsuba backend (:mod:`renderer_jobs.mitsuba.textures`); the Cycles backend
refuses them with a one-line error. UVs are the shapes' own (Mitsuba's rectangle, cube faces, sphere,
cylinder, meshes' ``vt``); ``scale`` repeats the texture ``(su, sv)`` times per unit of UV.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Discriminator, Field, Tag, model_validator

from illumix.scene.spectra import SpectrumSpec, StrictModel

PATTERNS = ("wood", "weave", "tiles", "stripes", "checker", "blobs", "picture")


class PatternTexture(StrictModel):
    """A procedural label map mixing ``spectra`` (see the module docstring). ``params``: per pattern —
    wood ``rings`` (per UV unit, 8), ``noise`` (0.35); weave ``threads`` (per UV unit, 48); tiles
    ``tiles`` (per UV unit, 4), ``grout`` (fraction of a tile, 0.06; label 0 is the grout); stripes
    ``stripes`` (mean count per UV unit, 12); checker ``cells`` (8); blobs ``blobs`` (features per UV
    unit, 4); picture ``shapes`` (12)."""

    pattern: Literal["wood", "weave", "tiles", "stripes", "checker", "blobs", "picture"]
    spectra: list[SpectrumSpec] = Field(min_length=2, max_length=32)
    seed: int = Field(default=0, ge=0, le=2**32 - 1)
    scale: tuple[float, float] = (1.0, 1.0)
    resolution: int = Field(default=256, ge=8, le=4096)
    params: dict[str, float] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _check(self) -> PatternTexture:
        if not all(np.isfinite(self.scale)) or min(self.scale) <= 0:
            raise ValueError("scale must be two positive numbers (repeats per UV unit)")
        known = _PARAMS[self.pattern]
        bad = sorted(set(self.params) - set(known))
        if bad:
            raise ValueError(f"pattern {self.pattern!r} has no parameter(s) {', '.join(bad)}; "
                             f"it takes {', '.join(known)}")
        if any(not np.isfinite(v) or v <= 0 for v in self.params.values()):
            raise ValueError("pattern parameters must be positive numbers")
        return self

    def label_map(self) -> np.ndarray:
        """The label map ``(resolution, resolution)`` float32, values in ``[0, K−1]``; row 0 is v = 0,
        as for Mitsuba's bitmaps (an image's first row lies along a rectangle's bottom edge)."""
        return _label_map(self.pattern, self.seed, self.resolution, len(self.spectra),
                          tuple(sorted({**_PARAMS[self.pattern], **self.params}.items())))


@lru_cache(maxsize=512)  # a scene is built once per group and per pass (probe, cubes): draw each map once
def _label_map(pattern: str, seed: int, resolution: int, k: int, params: tuple) -> np.ndarray:
    rng = np.random.default_rng([seed, PATTERNS.index(pattern)])
    t = np.clip(_GENERATORS[pattern](rng, resolution, k, dict(params)), 0, k - 1).astype(np.float32)
    t.flags.writeable = False  # shared by every caller
    return t


class BitmapTexture(StrictModel):
    """An sRGB image file (PNG or JPEG, path relative to the scene file), lifted to spectra by
    Jakob & Hanika 2019 (see the module docstring)."""

    file: str
    scale: tuple[float, float] = (1.0, 1.0)

    @model_validator(mode="after")
    def _check(self) -> BitmapTexture:
        if not all(np.isfinite(self.scale)) or min(self.scale) <= 0:
            raise ValueError("scale must be two positive numbers (repeats per UV unit)")
        if not self.file.lower().endswith((".png", ".jpg", ".jpeg")):
            raise ValueError(f"texture file {self.file!r}: give a PNG or JPEG image")
        return self


class NormalMap(StrictModel):
    """A tangent-space normal map (a material's ``normal_map``): an 8-bit RGB PNG whose texels
    ``c ∈ [0, 1]³`` are the unit normal ``2c − 1`` in the frame (∂p/∂u, n × ∂p/∂u, n) of the shape's
    UVs and shading normal — glTF's and Blender's convention (green = +v of an image with v up), read
    raw (no sRGB decoding). ``scale``: repeats per UV unit, as for :class:`BitmapTexture`. It bends
    shading normals only (Mitsuba's ``normalmap``); albedo and emission are unchanged."""

    file: str
    scale: tuple[float, float] = (1.0, 1.0)

    @model_validator(mode="after")
    def _check(self) -> NormalMap:
        if not all(np.isfinite(self.scale)) or min(self.scale) <= 0:
            raise ValueError("scale must be two positive numbers (repeats per UV unit)")
        if not self.file.lower().endswith(".png"):
            raise ValueError(f"normal map {self.file!r}: give an 8-bit RGB PNG")
        return self


Texture = Union[PatternTexture, BitmapTexture]


def _reflectance_kind(v) -> str:
    """Which branch a reflectance document is (so errors name that branch's fields only)."""
    if isinstance(v, dict):
        if "pattern" in v:
            return "pattern"
        if str(v.get("file", "")).lower().endswith((".png", ".jpg", ".jpeg")):
            return "bitmap"
        return "spectrum"
    return {PatternTexture: "pattern", BitmapTexture: "bitmap"}.get(type(v), "spectrum")


Reflectance = Annotated[Union[Annotated[SpectrumSpec, Tag("spectrum")], Annotated[PatternTexture, Tag("pattern")],
                              Annotated[BitmapTexture, Tag("bitmap")]], Discriminator(_reflectance_kind)]


def is_texture(spec) -> bool:
    return isinstance(spec, (PatternTexture, BitmapTexture))


# ---------------------------------------------------------------------------------------------
# Pattern generators: (rng, resolution n, number of spectra k, params) -> label map (n, n)

def _smooth_noise(rng: np.random.Generator, n: int, cells: int) -> np.ndarray:
    """Tileable value noise in [0, 1]: a ``cells``² random lattice, bicubically upsampled with wrap."""
    import cv2

    cells = max(2, int(round(cells)))
    lattice = rng.random((cells, cells)).astype(np.float32)
    pad = np.pad(lattice, 2, mode="wrap")
    big = cv2.resize(pad, ((cells + 4) * n // cells, (cells + 4) * n // cells), interpolation=cv2.INTER_CUBIC)
    off = 2 * n // cells
    out = big[off:off + n, off:off + n]
    lo, hi = float(out.min()), float(out.max())
    return (out - lo) / max(hi - lo, 1e-6)


def _uv(n: int) -> tuple[np.ndarray, np.ndarray]:
    c = (np.arange(n, dtype=np.float32) + 0.5) / n
    return np.meshgrid(c, c)


def _wood(rng, n, k, p):
    u, v = _uv(n)
    noise = _smooth_noise(rng, n, 6)
    # Rings around an axis along v, off the board: grain lines run along v, wobbling.
    cx = rng.uniform(-1.5, 2.5)
    r = np.abs(u - cx) * p["rings"] + p["noise"] * 3 * noise + 0.15 * np.sin(2 * np.pi * v * rng.integers(1, 3))
    s = 0.5 + 0.5 * np.sin(2 * np.pi * r)
    return (s ** 3) * (k - 1)


def _weave(rng, n, k, p):
    threads = max(2, int(p["threads"]))
    i = (np.arange(n) * threads // n)[:, None]
    j = (np.arange(n) * threads // n)[None, :]
    warp_over = ((i + j) % 4) < 2  # a 2/2 twill
    warp = np.broadcast_to(j % max(1, k // 2), (n, n))
    weft = np.broadcast_to(max(1, k // 2) + i % max(1, k - k // 2), (n, n))
    return np.where(warp_over, warp, np.minimum(weft, k - 1)).astype(np.float32)


def _tiles(rng, n, k, p):
    tiles = max(1, int(p["tiles"]))
    u, v = _uv(n)
    fu, fv = (u * tiles) % 1, (v * tiles) % 1
    g = p["grout"] / 2
    grout = (fu < g) | (fu > 1 - g) | (fv < g) | (fv > 1 - g)
    labels = rng.integers(1, k, size=(tiles, tiles)) if k > 2 else np.ones((tiles, tiles), int)
    tile = labels[(v * tiles).astype(int) % tiles, (u * tiles).astype(int) % tiles]
    return np.where(grout, 0, tile).astype(np.float32)


def _stripes(rng, n, k, p):
    widths = rng.uniform(0.4, 1.6, size=int(p["stripes"] * 3) + 2)
    edges = np.cumsum(widths) / widths[: max(1, int(p["stripes"]))].sum()
    labels = rng.integers(0, k, size=edges.size)
    u, _ = _uv(n)
    return labels[np.minimum(np.searchsorted(edges, u), edges.size - 1)].astype(np.float32)


def _checker(rng, n, k, p):
    cells = max(1, int(p["cells"]))
    i = (np.arange(n) * cells // n)[:, None]
    j = (np.arange(n) * cells // n)[None, :]
    return ((i + j) % k).astype(np.float32)


def _blobs(rng, n, k, p):
    return np.floor(_smooth_noise(rng, n, p["blobs"]) * k * 0.999)


def _picture(rng, n, k, p):
    u, v = _uv(n)
    out = np.zeros((n, n), np.float32) + rng.integers(0, k)
    for _ in range(int(p["shapes"])):
        cu, cv, a, b = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.05, 0.35), rng.uniform(0.05, 0.35)
        lab = rng.integers(0, k)
        if rng.random() < 0.5:
            m = (np.abs(u - cu) < a) & (np.abs(v - cv) < b)
        else:
            m = ((u - cu) / a) ** 2 + ((v - cv) / b) ** 2 < 1
        out[m] = lab
    return out


_GENERATORS = {"wood": _wood, "weave": _weave, "tiles": _tiles, "stripes": _stripes, "checker": _checker,
               "blobs": _blobs, "picture": _picture}
_PARAMS: dict[str, dict[str, float]] = {
    "wood": {"rings": 8.0, "noise": 0.35}, "weave": {"threads": 48.0}, "tiles": {"tiles": 4.0, "grout": 0.06},
    "stripes": {"stripes": 12.0}, "checker": {"cells": 8.0}, "blobs": {"blobs": 4.0}, "picture": {"shapes": 12.0},
}
