"""The export formats by name (case-insensitive, with aliases), the colour-science way.

- ``lsmi`` — the LSMI release's layout (Kim et al., ICCV 2021): 16-bit RGB TIFF raws, mixture
  ``.npy``, ``meta.json``, ``split.json`` and a template DNG per camera (:mod:`dataset_export.lsmi`);
- ``dng`` — the same layout with Bayer DNG raws in place of the TIFFs, as LSMI's cameras recorded
  them before its ``0_cvt2tiff.py`` (:mod:`imagefiles.dng`);
- ``exr`` — the store's spectral transport and illumination cubes as OpenEXR, one channel per band
  (:mod:`imagefiles.spectral_exr`; no camera, no illuminant: the cubes are what every sample is composed from).
"""

from __future__ import annotations

from dataclasses import dataclass

from illumix.retarget.registry import MethodRegistry


@dataclass(frozen=True)
class ExportFormat:
    """What a format writes: ``raw_ext`` the raw frame's file extension (``None``: no frames, cubes);
    ``bayer``: frames are composed as a colour-filter-array mosaic; ``modules``: the packages of the
    ``export`` extra it writes with (checked before any work)."""

    name: str
    raw_ext: str | None
    bayer: bool = False
    modules: tuple[str, ...] = ()


EXPORT_FORMATS: MethodRegistry[ExportFormat] = MethodRegistry("export format", {
    "lsmi": ExportFormat("lsmi", ".tiff", modules=("pidng",)),  # the template DNG
    "dng": ExportFormat("dng", ".dng", bayer=True, modules=("pidng",)),
    "exr": ExportFormat("exr", None, modules=("OpenEXR",)),
}, aliases={"tiff": "lsmi", "openexr": "exr", "spectral exr": "exr", "raw": "dng"})
