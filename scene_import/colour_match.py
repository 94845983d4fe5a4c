"""Colours of imported scenes as illumix spectra: reflectances, light colours, texture images.

- **Reflectances**: a linear sRGB colour (glTF ``baseColorFactor``, MTL ``Kd``, Mitsuba ``<rgb>``) becomes
  the smooth Jakob & Hanika (2019) spectrum whose colour under D65 (CIE 1931 2°) is that colour
  (:func:`jakob_hanika`: colour-science's ``XYZ_to_sd_Jakob2019``,
  380–780 nm / 5 nm, given inline). Grey colours become a constant spectrum (exact, and no optimiser run).
- **Light colours** are reduced to a chromaticity ``xy`` (CIE 1931) and a luminance factor ``Y``
  (linear sRGB white ``(1, 1, 1)`` and the flat unit spectrum both have ``Y = 1``). A light group's
  emission is then the CIE illuminant nearest in CIE 1960 ``uv`` (:func:`illuminant_for`): a named one
  (A, D50, D55, D65, D75) when it is as close as the parametric ones, else ``daylight:K`` or
  ``blackbody:K`` at the colour's correlated colour temperature (Ohno 2013). Illuminants are
  photometrically normalised in illumix (:mod:`retarget.illuminants`), so an emitter's strength is its
  luminance in the source file's units times ``Y``.
- **Texture images** are 8-bit sRGB files; a constant factor (glTF ``baseColorFactor`` on a texture) is
  baked into the pixels in linear light, because illumix bitmap textures carry no factor.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import numpy as np

from illumix.retarget.isp import encode_srgb

NAMED = ("A", "D50", "D55", "D65", "D75")  # named CIE illuminants preferred when they fit as well
NAMED_SLACK_UV = 8e-4  # how much further (CIE 1960 uv) a named illuminant may be than the CCT one
CCT_RANGE = (1000.0, 25000.0)  # K; outside it xy→CCT is unreliable and no lamp lives there
GREY_SPREAD = 1e-4  # a colour whose channels differ by less than this is grey: a constant spectrum



# -- reflectances --------------------------------------------------------------------------------


def reflectance(rgb, what: str, warn: Callable[[str], None]) -> dict:
    """The reflectance spectrum spec (a schema ``reflectance`` dict) of a linear sRGB colour in [0, 1].

    Grey → ``{"value": v}``; otherwise Jakob–Hanika inline table. Out-of-range components are
    clipped and colours the smooth spectra cannot reach are approximated, each with a warning."""
    c = np.asarray(rgb, dtype=float)[:3]
    if not np.all(np.isfinite(c)):
        warn(f"{what}: colour {c.tolist()} is not finite; used grey 0.5")
        return {"value": 0.5}
    if np.any(c < 0) or np.any(c > 1):
        warn(f"{what}: colour {np.round(c, 4).tolist()} is outside [0, 1]; clipped")
        c = np.clip(c, 0.0, 1.0)
    if float(c.max() - c.min()) <= GREY_SPREAD:
        return {"value": round(float(c.mean()), 6)}
    values, err = jakob_hanika(tuple(round(float(x), 6) for x in c))
    if err > 1.0:
        warn(f"{what}: no reflectance spectrum reproduces colour {np.round(c, 3).tolist()} closely "
             f"(ΔE2000 {err:.1f}); used the closest smooth spectrum")
    return {"wavelengths": JH_WAVELENGTHS.tolist(), "values": list(values)}


JH_WAVELENGTHS = np.arange(380.0, 781.0, 5.0)  # nm, the upsampled reflectances' table


@lru_cache(maxsize=4096)
def jakob_hanika(rgb: tuple[float, float, float]) -> tuple[tuple[float, ...], float]:
    """``(values on JH_WAVELENGTHS in [0, 1], ΔE2000 error)``: the smooth Jakob & Hanika (2019) spectrum
    whose colour under D65 (CIE 1931 2°) is the linear sRGB ``rgb`` (colour-science's fit; here, not in
    the Blender importer, so that every importer depends on this module and not the reverse)."""
    import colour
    from colour.recovery import XYZ_to_sd_Jakob2019

    shape = colour.SpectralShape(380, 780, 5)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    xyz = colour.RGB_to_XYZ(np.asarray(rgb), colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False)
    sd, err = XYZ_to_sd_Jakob2019(xyz, cmfs, d65, additional_data=True)
    return tuple(np.round(np.clip(sd.copy().align(shape).values, 0.0, 1.0), 6).tolist()), float(err)


def mean_rgb(values) -> np.ndarray:
    """Mean linear colour ``(3,)`` of an image array ``(H, W, ≥3)`` of 8-bit sRGB codes."""
    a = np.asarray(values)[..., :3].astype(np.float64) / 255.0
    return srgb_decode(a).reshape(-1, 3).mean(axis=0)


def srgb_decode(v: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] → linear (IEC 61966-2-1)."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def write_texture(image, factor, path: Path) -> None:
    """Write a PIL image as an 8-bit sRGB PNG at ``path``, times the linear ``factor`` ``(3,)`` (the
    alpha channel is dropped: illumix materials are opaque)."""
    from PIL import Image

    rgb = image.convert("RGB")
    f = np.asarray(factor, dtype=float)[:3]
    if not np.allclose(f, 1.0):
        a = srgb_decode(np.asarray(rgb, dtype=np.float64) / 255.0) * np.clip(f, 0.0, 1.0)
        rgb = Image.fromarray(np.round(encode_srgb(a) * 255.0).astype(np.uint8), "RGB")
    path.parent.mkdir(parents=True, exist_ok=True)
    rgb.save(path, format="PNG")


# -- light colours --------------------------------------------------------------------------------


def rgb_light(rgb) -> tuple[np.ndarray | None, float]:
    """``(xy, Y)`` of a linear sRGB light colour (``xy`` None when it is black)."""
    import colour

    # sRGB (linear, D65) → CIE XYZ, Y of white = 1 (IEC 61966-2-1)
    xyz = colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ @ np.clip(np.asarray(rgb, dtype=float)[:3], 0.0, None)
    s = float(xyz.sum())
    return (xyz[:2] / s if s > 0 else None), float(xyz[1])


@lru_cache(maxsize=1)
def _cmfs_1nm() -> tuple[np.ndarray, np.ndarray]:
    import colour

    c = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return c.wavelengths, c.values


def spectrum_light(wavelengths, values) -> tuple[np.ndarray | None, float]:
    """``(xy, Y)`` of an emission spectrum sampled at ``wavelengths`` (nm), linearly interpolated and
    zero outside its samples; ``Y`` relative to the flat unit spectrum over the CIE observer's range."""
    wl, cmf = _cmfs_1nm()
    s = np.interp(wl, np.asarray(wavelengths, float), np.asarray(values, float), left=0.0, right=0.0)
    xyz = cmf.T @ s
    y = float(xyz[1] / cmf[:, 1].sum())
    return (xyz[:2] / xyz.sum() if xyz.sum() > 0 else None), y


def _uv(xy) -> np.ndarray:
    x, y = float(xy[0]), float(xy[1])
    d = -2 * x + 12 * y + 3
    return np.array([4 * x / d, 6 * y / d])


@lru_cache(maxsize=256)
def illuminant_xy(name: str) -> tuple[float, float]:
    """Chromaticity of a named illumix illuminant (CIE 1931, on the default grid)."""
    from illumix.retarget.grid import DEFAULT_GRID, resample
    from illumix.retarget.illuminants import illuminant_spd

    wl, cmf = _cmfs_1nm()
    bars = np.stack([resample(wl, cmf[:, i], DEFAULT_GRID) for i in range(3)])
    xyz = bars @ illuminant_spd(name, DEFAULT_GRID)
    return float(xyz[0] / xyz.sum()), float(xyz[1] / xyz.sum())


def uv_distance(xy, name: str) -> float:
    """CIE 1960 ``Δuv`` between a chromaticity and an illuminant's."""
    return float(np.linalg.norm(_uv(xy) - _uv(illuminant_xy(name))))


def cct_duv(xy) -> tuple[float, float]:
    """Correlated colour temperature (K) and ``Duv`` of a chromaticity (Ohno 2013)."""
    from colour.temperature import uv_to_CCT

    cct, duv = uv_to_CCT(_uv(xy), method="Ohno 2013")
    return float(cct), float(duv)


def illuminant_for(xy) -> tuple[str, float]:
    """``(illuminant name, CCT in K)``: the CIE illuminant nearest the chromaticity (module docstring).

    CCT is clamped to :data:`CCT_RANGE`; ``daylight:K`` exists for 4000–25000 K only."""
    import colour

    cct, _ = cct_duv(xy)
    cct = float(np.clip(cct if np.isfinite(cct) else 6504.0, *CCT_RANGE))
    candidates = [f"blackbody:{round(cct, -1):.0f}"]
    if cct >= 4000:
        # daylight:K is parameterised by the nominal CCT (old c2, as D65 is "6500 K")
        with warnings.catch_warnings():  # its domain note near 4000 K; the range is checked below
            warnings.simplefilter("ignore")
            k = colour.temperature.xy_to_CCT_CIE_D(np.asarray(xy, float)) * 1.4380 / 1.4388
        if 4000 <= k <= 25000:
            candidates.append(f"daylight:{round(float(k), -1):.0f}")
    best = min(candidates, key=lambda n: uv_distance(xy, n))
    d_best = uv_distance(xy, best)
    named = min(NAMED, key=lambda n: uv_distance(xy, n))
    if uv_distance(xy, named) <= d_best + NAMED_SLACK_UV:
        return named, cct
    return best, cct


# -- exact emission spectra ------------------------------------------------------------------------

EDGE_NM = (390.0, 710.0)  # a table is zero-extended to cover at least this (the default grid's 392.5–707.5)


def luminance_factor(wavelengths, values) -> float:
    """``Y`` of a spectrum relative to the flat unit spectrum, on the default grid — the factor by which
    illumix's photometric normalisation (:func:`retarget.illuminants.normalise`) divides it."""
    from illumix.retarget.grid import DEFAULT_GRID, resample
    from illumix.retarget.illuminants import spd_from_samples

    raw = resample(np.asarray(wavelengths, float), np.asarray(values, float), DEFAULT_GRID)
    norm = spd_from_samples(np.asarray(wavelengths, float), np.asarray(values, float), DEFAULT_GRID)
    k = int(np.argmax(norm))
    return float(raw[k] / norm[k])


def table_light(wavelengths, values) -> tuple[dict | None, np.ndarray | None, float]:
    """``(table spectrum spec, xy, Y)`` of an emission sampled at ``wavelengths`` (nm): zero outside its
    samples (as Mitsuba's irregular spectrum), normalised so that ``Y ×`` illumix's normalised table is
    the given spectrum. ``(None, None, 0)`` when it has no luminance."""
    wl, v = np.asarray(wavelengths, float), np.asarray(values, float)
    order = np.argsort(wl)
    wl, v = wl[order], np.clip(v[order], 0.0, None)
    if wl[0] > EDGE_NM[0]:
        wl, v = np.r_[EDGE_NM[0], wl[0] - 1e-3, wl], np.r_[0.0, 0.0, v]
    if wl[-1] < EDGE_NM[1]:
        wl, v = np.r_[wl, wl[-1] + 1e-3, EDGE_NM[1]], np.r_[v, 0.0, 0.0]
    xy, _ = spectrum_light(wl, v)
    if xy is None or not np.any(v > 0):
        return None, None, 0.0
    y = luminance_factor(wl, v)
    spec = {"wavelengths": [round(float(x), 6) for x in wl], "values": [float(f"{x:.9g}") for x in v / y]}
    return spec, xy, y


def blackbody_light(kelvin: float) -> tuple[str, np.ndarray, float]:
    """``("blackbody:K", xy, Y)`` of Planck's spectral radiance at ``kelvin`` in W/(m²·sr·nm), as Mitsuba
    3's ``blackbody`` spectrum emits it; ``Y`` relative to the flat unit spectrum."""
    import colour

    wl = np.arange(360.0, 831.0, 1.0)
    v = colour.colorimetry.planck_law(wl * 1e-9, float(kelvin)) * 1e-9  # W/(sr·m²·m) → per nm
    xy, _ = spectrum_light(wl, v)
    return f"blackbody:{float(kelvin):g}", xy, luminance_factor(wl, v)
