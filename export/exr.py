"""Spectral OpenEXR images: one channel per band, named as Fichet, Pacanowski & Wilkie (2021), "An
OpenEXR Layout for Spectral Images", JCGT 10(3) propose.

An emissive (radiance) spectral image has one channel per wavelength, named ``S0.<wavelength><unit>``
— ``S0`` the first Stokes component (unpolarised radiance), the wavelength written with a comma as
its decimal separator because the dot separates OpenEXR layers: ``S0.550,0nm``. Names are written
exactly as colour-science's implementation of the paper writes them
(:func:`colour.io.write_spectral_image_Fichet2021`: ``str(float(λ)).replace(".", ",")``) and read
with its pattern (``colour.io.fichet2021.PATTERN_FICHET2021``), so any reader of the layout parses
them. The header carries the paper's ``spectralLayoutVersion`` (``"1.0"``) and ``emissiveUnits``
attributes; illumix's own attributes (``illumix*``) say what the values are.

Values are the store's cubes as they are (band integrals over 5 nm, relative radiometric units: a
group's cube is its radiance for its recorded emission, see ``illumixEmission``), in ``float32`` or
``float16``. float32 round-trips exactly. float16 holds values up to 65504: larger ones (directly seen
emitters) are clipped to it and counted in ``illumixClippedToHalf`` — never written as inf.
Written with the OpenEXR Python bindings (ZIP compression, lossless).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

HALF_MAX = 65504.0
EXR_DTYPES = {"float32": np.float32, "float16": np.float16}


def channel_name(wavelength_nm: float) -> str:
    """``S0.550,0nm`` for 550 nm (module docstring)."""
    return f"S0.{str(float(wavelength_nm)).replace('.', ',')}nm"


def spectrum_attribute(wavelengths, values) -> str:
    """A spectrum as the paper's attribute string ``"395.000000nm:1.000000;…"`` (colour-science's
    :func:`colour.io.sd_to_spectrum_attribute_Fichet2021` format, 6 decimals)."""
    return ";".join(f"{w:.6f}nm:{v:.6f}" for w, v in zip(wavelengths, values))


def write_spectral_exr(path: Path, cube: np.ndarray, wavelengths, *, dtype: str = "float32",
                       attributes: dict[str, str] | None = None) -> int:
    """Write ``cube`` ``(H, W, bands)`` with one channel per entry of ``wavelengths`` (nm); returns the
    number of values clipped to the float16 range (0 for float32)."""
    import OpenEXR

    cube = np.asarray(cube, np.float32)
    if cube.ndim != 3 or cube.shape[2] != len(wavelengths):
        raise ValueError(f"cube {cube.shape} does not have {len(wavelengths)} bands")
    clipped = 0
    if dtype == "float16":
        over = np.abs(cube) > HALF_MAX
        clipped = int(np.count_nonzero(over))
        cube = np.clip(cube, -HALF_MAX, HALF_MAX) if clipped else cube
    npt = EXR_DTYPES[dtype]
    channels = {channel_name(w): np.ascontiguousarray(cube[..., i].astype(npt)) for i, w in enumerate(wavelengths)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              "spectralLayoutVersion": "1.0", "emissiveUnits": "W.m^-2.sr^-1",
              "illumixClippedToHalf": str(clipped), **(attributes or {})}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))
    return clipped


def read_spectral_exr(path: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """``(wavelengths (bands,) nm ascending, cube (H, W, bands) in the file's dtype, header)`` of a
    spectral EXR's ``S0`` channels (any Fichet et al. 2021 wavelength spelling)."""
    import OpenEXR
    from colour.io.fichet2021 import PATTERN_FICHET2021, match_groups_to_nm

    pattern = re.compile(rf"^S0\.{PATTERN_FICHET2021}$")
    with OpenEXR.File(str(path)) as f:
        header = dict(f.header())
        bands = []
        for name, ch in f.channels().items():
            m = pattern.match(name)
            if m:
                bands.append((match_groups_to_nm(m.group(1), m.group(3) or "", m.group(4)), ch.pixels))
    if not bands:
        raise ValueError(f"{path}: no S0.<wavelength> channels (not a Fichet et al. 2021 emissive image)")
    bands.sort(key=lambda b: b[0])
    return np.array([b[0] for b in bands]), np.stack([b[1] for b in bands], axis=-1), header
