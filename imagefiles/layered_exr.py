"""A sample's outputs as one multi-channel OpenEXR: every output a layer, every value float32.

Channel names follow OpenEXR's layer convention, ``<layer>.<channel>`` (the last dot separates the
channel from its layer; OpenEXR viewers group and display layers by it), the layer named after the
output (``GET /sample``'s names):

============================================  ===================  ====================================
output                                        shape                channels
============================================  ===================  ====================================
``raw``, ``gain``, ``srgb``, ``illum``,       ``(H, W, 3)``        ``raw.R``, ``raw.G``, ``raw.B``
``albedo``
``normal``                                    ``(H, W, 3)``        ``normal.X``, ``normal.Y``, ``normal.Z``
``ccm``                                       ``(H, W, 3, 3)``     ``ccm.RR``, ``ccm.RG`` … ``ccm.BB``: row
                                                                   (linear sRGB out), column (camera in)
``weights``, ``mixture``                      ``(H, W, groups)``   ``mixture.<group>`` (the light group's
                                                                   name, dots made ``_``)
``mask``, ``depth``, ``raw`` with ``bayer=``  ``(H, W)``           the output's name (``mask``: 1.0 / 0.0)
``illumination``                              ``(H, W, bands)``    ``S0.<λ>nm`` (Fichet et al. 2021,
                                                                   emissive: ``S0.550,0nm``)
``reflectance``                               ``(H, W, bands)``    ``T.<λ>nm`` (Fichet et al. 2021,
                                                                   reflective)
============================================  ===================  ====================================

Other arrays get ``<name>.0``, ``<name>.1``, … along their last axis. The spectra follow
:mod:`imagefiles.spectral_exr`, so readers of Fichet et al.'s layout (colour-science's
``read_spectral_image_Fichet2021``) find them; the header then carries ``spectralLayoutVersion``
(and, with ``S0``, ``emissiveUnits`` and ``illumixBandWidthNm``: relative band integrals, see
:mod:`imagefiles.spectral_exr` "Units"). The header's ``illumixLayers`` (JSON ``{output: {"channels":
[…], "shape": […], "dtype": …}}``) says which channels make which array in which order, so
:func:`read_layered_exr` rebuilds every array exactly (float32 is written as it is; bool as 1.0/0.0;
integers as float32, exact below 2²⁴); ``illumixMeta`` holds the sample's metadata JSON when given.
ZIP compression (lossless), written with the OpenEXR Python bindings (through a temporary file: the
bindings of the ``export`` extra's range read and write paths only).
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from illumix.imagefiles.spectral_exr import (
    EMISSIVE,
    REFLECTIVE,
    channel_name,
    layout_attributes,
)

RGB = ("R", "G", "B")
COMPONENTS = {"normal": ("X", "Y", "Z")}  # 3-channel outputs that are not colours
PER_GROUP = ("weights", "mixture")
SPECTRAL = {"illumination": EMISSIVE, "reflectance": REFLECTIVE}
LAYERS_ATTRIBUTE, META_ATTRIBUTE = "illumixLayers", "illumixMeta"


def _safe(name: str) -> str:
    return str(name).replace(".", "_")


def channel_names(name: str, shape: tuple[int, ...], *, groups=(), wavelengths=()) -> list[str]:
    """The channel names of output ``name`` shaped ``shape``, in the array's C order (module table)."""
    if len(shape) == 2:
        return [name]
    if name in SPECTRAL and len(shape) == 3 and shape[2] == len(wavelengths):
        return [channel_name(w, SPECTRAL[name]) for w in wavelengths]
    if len(shape) == 4 and shape[2:] == (3, 3):
        return [f"{name}.{r}{c}" for r in RGB for c in RGB]
    n = int(np.prod(shape[2:]))
    if name in PER_GROUP and n == len(groups) and len({_safe(g) for g in groups}) == n:
        parts = [_safe(g) for g in groups]
    elif len(shape) == 3 and n == 3:
        parts = list(COMPONENTS.get(name, RGB))
    else:
        parts = [str(i) for i in range(n)]
    return [f"{name}.{p}" for p in parts]


def layered_channels(arrays: dict[str, np.ndarray], *, groups=(), wavelengths=()
                     ) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
    """``(channels {name: (H, W) float32}, layers {output: {"channels", "shape", "dtype"}})`` of ``arrays``."""
    channels, layers = {}, {}
    for name, a in arrays.items():
        names = channel_names(name, a.shape, groups=groups, wavelengths=wavelengths)
        clash = set(names) & set(channels)
        if clash:
            raise ValueError(f"output {name!r}: channels {sorted(clash)} already written by another output")
        planes = a.reshape(*a.shape[:2], -1)
        for i, c in enumerate(names):
            channels[c] = np.ascontiguousarray(planes[..., i], dtype=np.float32)
        layers[name] = {"channels": names, "shape": list(a.shape), "dtype": a.dtype.str}
    return channels, layers


def layered_exr_bytes(arrays: dict[str, np.ndarray], *, groups=(), wavelengths=(), meta: str | None = None,
                      attributes: dict[str, str] | None = None) -> bytes:
    """The OpenEXR file of ``arrays`` (each ``(H, W, …)``, one frame size) as bytes (module docstring).

    groups : the light groups' names (``weights``/``mixture`` channels); wavelengths : band centres in
    nm (``illumination``/``reflectance`` channels); meta : JSON text for ``illumixMeta``."""
    import OpenEXR

    channels, layers = layered_channels(arrays, groups=groups, wavelengths=wavelengths)
    if not channels:
        raise ValueError("no arrays to write: an OpenEXR image needs at least one channel")
    components = {c.split(".")[0] for c in channels}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              LAYERS_ATTRIBUTE: json.dumps(layers), **(attributes or {})}
    if components & set(SPECTRAL.values()):
        header.update(layout_attributes(components, wavelengths))
    if meta is not None:
        header[META_ATTRIBUTE] = meta
    with tempfile.TemporaryDirectory(prefix="illumix-exr-") as tmp:
        path = Path(tmp) / "sample.exr"
        with OpenEXR.File(header, channels) as f:
            f.write(str(path))
        return path.read_bytes()


def read_layered_exr(source: Path | bytes) -> tuple[dict[str, np.ndarray], dict]:
    """``(arrays, header)`` of a file :func:`layered_exr_bytes` wrote (a path or its bytes): each
    output rebuilt from its channels with its shape and dtype (``illumixLayers``)."""
    import OpenEXR

    with tempfile.TemporaryDirectory(prefix="illumix-exr-") as tmp:
        if isinstance(source, (bytes, bytearray, memoryview)):
            path = Path(tmp) / "sample.exr"
            path.write_bytes(source)
        else:
            path = Path(source)
        with OpenEXR.File(str(path), separate_channels=True) as f:
            header = dict(f.header())
            planes = {name: ch.pixels for name, ch in f.channels().items()}
    if LAYERS_ATTRIBUTE not in header:
        raise ValueError(f"{source if isinstance(source, Path) else 'the file'}: no {LAYERS_ATTRIBUTE} attribute "
                         "(not written by illumix); read its channels with OpenEXR directly")
    arrays = {}
    for name, layer in json.loads(header[LAYERS_ATTRIBUTE]).items():
        stack = np.stack([planes[c] for c in layer["channels"]], axis=-1)
        arrays[name] = stack.reshape(layer["shape"]).astype(np.dtype(layer["dtype"]))
    return arrays, header
