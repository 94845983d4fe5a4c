"""Spectral OpenEXR images: one channel per band, named as Fichet, Pacanowski & Wilkie (2021), "An
OpenEXR Layout for Spectral Images", JCGT 10(3) propose.

A spectral image has one channel per wavelength, named ``<component>.<wavelength><unit>``: ``S0``
(the first Stokes component, unpolarised radiance) for an emissive image, ``T`` for a reflective
one (reflectance, transmittance), the wavelength written with a comma as its decimal separator
because the dot separates OpenEXR layers: ``S0.550,0nm``, ``T.550,0nm``. Names are written exactly
as colour-science's implementation of the paper writes them
(:func:`colour.io.write_spectral_image_Fichet2021`: ``str(float(λ)).replace(".", ",")``) and read
with its pattern (``colour.io.fichet2021.PATTERN_FICHET2021``), so any reader of the layout parses
them. The header carries the paper's ``spectralLayoutVersion`` (``"1.0"``) and, for emissive
channels, ``emissiveUnits``; illumix's own attributes (``illumix*``) say what the values are.

Units. illumix's spectra are **relative** and **band integrals**: a channel holds the radiance over
its band ``[λ − Δλ/2, λ + Δλ/2]`` (Δλ = ``illumixBandWidthNm``, 5 nm on the default grid), for the
group's recorded emission (``illumixEmission``), in no absolute unit. ``emissiveUnits`` says so
(:data:`EMISSIVE_UNITS`) rather than claiming the paper's absolute ``W.m^-2.sr^-1``. The values are
written as illumix holds them, so they read back exactly; a reader that takes ``S0`` as a spectral
density and integrates ``Σ S(λ) Δλ`` gets Δλ × the relative radiance — the same factor for every
pixel, band and file of a grid, so relative scales hold; divide by ``illumixBandWidthNm`` for a
density per nm (and for comparisons across grids of different band widths).

``illumix export --format exr`` writes the store's cubes this way (:mod:`dataset_export.exr_layout`),
in ``float32`` or ``float16``. float32 round-trips exactly.
float16 holds values up to 65504: larger ones (directly seen emitters) are clipped to it and counted
in ``illumixClippedToHalf`` — never written as inf. ``GET /sample?format=exr`` puts a sample's
``illumination`` (``S0``) and ``reflectance`` (``T``) spectra in its file the same way
(:mod:`imagefiles.layered_exr`). Written with the OpenEXR Python bindings (ZIP compression, lossless).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

HALF_MAX = 65504.0
EXR_DTYPES = {"float32": np.float32, "float16": np.float16}
EMISSIVE, REFLECTIVE = "S0", "T"  # Fichet et al.'s component names: radiance, reflectance
LAYOUT_VERSION = "1.0"
EMISSIVE_UNITS = "relative (band integrals over illumixBandWidthNm; no absolute unit)"
BAND_WIDTH_ATTRIBUTE = "illumixBandWidthNm"


def channel_name(wavelength_nm: float, component: str = EMISSIVE) -> str:
    """``S0.550,0nm`` for 550 nm (``T.550,0nm`` for a reflective component; module docstring)."""
    return f"{component}.{str(float(wavelength_nm)).replace('.', ',')}nm"


def spectrum_attribute(wavelengths, values) -> str:
    """A spectrum as the paper's attribute string ``"395.000000nm:1.000000;…"`` (colour-science's
    :func:`colour.io.sd_to_spectrum_attribute_Fichet2021` format, 6 decimals)."""
    return ";".join(f"{w:.6f}nm:{v:.6f}" for w, v in zip(wavelengths, values))


def spectral_channels(cube: np.ndarray, wavelengths, component: str = EMISSIVE, dtype=np.float32
                      ) -> dict[str, np.ndarray]:
    """``{channel name: (H, W) plane}`` of ``cube`` ``(H, W, bands)``, one per entry of ``wavelengths`` (nm)."""
    if cube.ndim != 3 or cube.shape[2] != len(wavelengths):
        raise ValueError(f"cube {cube.shape} does not have {len(wavelengths)} bands")
    return {channel_name(w, component): np.ascontiguousarray(cube[..., i], dtype=dtype)
            for i, w in enumerate(wavelengths)}


def layout_attributes(components, wavelengths=()) -> dict[str, str]:
    """The paper's header attributes for a file holding ``components`` (``S0`` needs its units, and
    illumix adds the band width its units refer to: the grid's step, from ``wavelengths`` in nm)."""
    attrs = {"spectralLayoutVersion": LAYOUT_VERSION}
    if EMISSIVE in components:
        attrs["emissiveUnits"] = EMISSIVE_UNITS
        if len(wavelengths) > 1:
            attrs[BAND_WIDTH_ATTRIBUTE] = repr(float(np.median(np.diff(np.asarray(wavelengths, np.float64)))))
    return attrs


def write_spectral_exr(path: Path, cube: np.ndarray, wavelengths, *, dtype: str = "float32",
                       attributes: dict[str, str] | None = None) -> int:
    """Write ``cube`` ``(H, W, bands)`` as an emissive image, one channel per entry of ``wavelengths``
    (nm); returns the number of values clipped to the float16 range (0 for float32)."""
    import OpenEXR

    cube = np.asarray(cube, np.float32)
    clipped = 0
    if dtype == "float16":
        over = np.abs(cube) > HALF_MAX
        clipped = int(np.count_nonzero(over))
        cube = np.clip(cube, -HALF_MAX, HALF_MAX) if clipped else cube
    channels = spectral_channels(cube, wavelengths, EMISSIVE, EXR_DTYPES[dtype])
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              **layout_attributes([EMISSIVE], wavelengths), "illumixClippedToHalf": str(clipped), **(attributes or {})}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))
    return clipped


def read_spectral_exr(path: Path, component: str = EMISSIVE) -> tuple[np.ndarray, np.ndarray, dict]:
    """``(wavelengths (bands,) nm ascending, cube (H, W, bands) in the file's dtype, header)`` of a
    spectral EXR's ``component`` channels (``S0`` or ``T``; any Fichet et al. 2021 wavelength spelling)."""
    import OpenEXR
    from colour.io.fichet2021 import PATTERN_FICHET2021, match_groups_to_nm

    pattern = re.compile(rf"^{re.escape(component)}\.{PATTERN_FICHET2021}$")
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = dict(f.header())
        bands = []
        for name, ch in f.channels().items():
            m = pattern.match(name)
            if m:
                bands.append((match_groups_to_nm(m.group(1), m.group(3) or "", m.group(4)), ch.pixels))
    if not bands:
        raise ValueError(f"{path}: no {component}.<wavelength> channels (not a Fichet et al. 2021 spectral image)")
    bands.sort(key=lambda b: b[0])
    return np.array([b[0] for b in bands]), np.stack([b[1] for b in bands], axis=-1), header
