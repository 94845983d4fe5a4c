"""``GET /sample?format=dng|exr``: the sample as a camera raw file or as one OpenEXR image.

- ``dng``: one Bayer DNG of ``raw`` (:mod:`imagefiles.dng`; CFA ``bayer=``, RGGB when not given;
  ``bayer=none``: a LinearRaw DNG of the RGB raw, three samples per pixel),
  exposed as the PNG of raw is (auto exposure, thesis eq. 4.2, unless ``exposure=`` is given: 1.0 is
  the white level, highlights clip) and quantised to digital numbers like ``illumix export``'s
  frames: with ``noise=``, the sensor model's digital numbers, black and white level; without, the
  export's default sensor levels (black 64, white 4095: 12 bits) with ``DN = round(64 + raw · (4095 −
  64))`` clipped to [0, 4095] (:func:`retarget.sensor_model.simulate_raw` without noise): the digital
  numbers, levels, matrix and neutral ``illumix export --format dng`` writes for the same
  parameters. ``ColorMatrix1``: the sensor's under D65 (:func:`imagefiles.dng.color_matrix`); ``AsShotNeutral``: the ground-truth
  white point (:func:`imagefiles.dng.as_shot_neutral`: one lit group's white point; for mixed
  light the mean mixed white point over the valid pixels). libraw opens frames of 22 × 22 pixels
  and more: smaller ones are refused.
- ``exr``: every requested output in one float32 OpenEXR, a layer per output (``raw.R``,
  ``mixture.<group>``, ``mask``, spectra as Fichet et al. 2021's ``S0.<λ>nm`` / ``T.<λ>nm``;
  :mod:`imagefiles.layered_exr`), the metadata in its ``illumixMeta`` attribute when asked for.

Both write with the ``export`` extra's packages (pidng, OpenEXR): without them the answer is a 501
naming the install, before any work.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from illumix.engine import budget
from illumix.engine.spec import SampleSpec
from illumix.imagefiles.dng import DNG_LEVELS, DNG_MIN_SIDE, dng_levels, noise_profile
from illumix.retarget.errors import SpectralError
from illumix.retarget.sensor_model import simulate_raw
from illumix.service.errors import fail

FILE_FORMATS = ("dng", "exr")
MODULES = {"dng": "pidng", "exr": "OpenEXR"}
DNG_OUTPUTS = ("raw", "mixture", "mask", "meta")  # composed for a DNG: the mixture and mask give its neutral


def require(fmt: str) -> None:
    """A 501 when the package writing ``fmt`` is not installed (checked before any work)."""
    module = MODULES[fmt]
    if importlib.util.find_spec(module) is None:
        raise fail(501, f"format={fmt} needs the {module} package, which this service does not have; install "
                        "it with `pip install 'illumix[export]'` and restart the service, or ask format=npz",
                   code="not_installed", loc=["query", "format"])


def compose_spec(spec: SampleSpec) -> SampleSpec:
    """What to compose for ``spec``: a DNG needs the raw (the ``bayer=`` mosaic; when not given the
    camera's own with ``noise=camera``, else RGGB (:func:`engine.plan._mosaic`); RGB for ``bayer=none``),
    the mixture, the mask and the metadata. A 501 when the package writing the format is not installed (:func:`require`)."""
    if spec.format in FILE_FORMATS:
        require(spec.format)
    if spec.format != "dng":
        return spec
    return spec.model_copy(update={"outputs": list(DNG_OUTPUTS)})  # the plan picks the mosaic (engine.plan)


def check(p) -> None:
    """Refusals that need the plan: a DNG smaller than libraw reads."""
    if p.spec.format == "dng" and min(p.out_size) < DNG_MIN_SIDE:
        w, h = p.out_size
        raise SpectralError(f"format=dng needs a frame of at least {DNG_MIN_SIDE}x{DNG_MIN_SIDE} pixels (libraw, "
                            f"which most raw tools read with, refuses smaller ones); got {w}x{h}: ask a larger "
                            "crop= or size=")


def extra_bytes(p) -> int:
    """Memory beyond :func:`engine.sampling.price`: an EXR holds a float32 copy of every output's
    planes while its file is written."""
    if p.spec.format != "exr":
        return 0
    w, h = p.out_size
    return budget.output_bytes(p.spec.array_outputs(), len(p.groups), w * h, p.metas[0].n_bands)


def headers(meta: dict, fmt: str) -> dict[str, str]:
    """The answer's headers: ``Content-Disposition`` with the file name ``<scene>-<view>-<seed>.<fmt>``
    (anything but letters, digits, ``-``, ``_`` and ``.`` as ``_``) and ``X-Illumix-Meta`` (what and
    how: scene, view, seed, size, exposure gain; a DNG's levels, CFA and neutral under ``encoding``)."""
    from illumix.service.encoding import meta_json

    stem = "".join(c if c.isascii() and (c.isalnum() or c in "-_.") else "_"
                   for c in f"{meta['scene']}-{meta['view']}-{meta['seed']}")
    about = {k: meta[k] for k in ("scene", "view", "seed", "size", "exposure_gain", "encoding") if k in meta}
    return {"Content-Disposition": f'attachment; filename="{stem}.{fmt}"', "X-Illumix-Meta": meta_json(about)}


def encode(p, ctx, arrays: dict[str, np.ndarray], meta: dict, with_meta: bool) -> tuple[bytes, dict[str, str]]:
    """``(body, headers)`` of a sample planned from :func:`compose_spec` (``with_meta``: the EXR carries the
    metadata)."""
    if p.spec.format == "dng":
        body = encode_dng(p, ctx, arrays, meta)
    else:
        body = encode_exr(p, arrays, meta if with_meta else None)
    return body, headers(meta, p.spec.format)


def encode_dng(p, ctx, arrays: dict[str, np.ndarray], meta: dict) -> bytes:
    """The DNG of a sample composed with :func:`compose_spec` (module docstring)."""
    from illumix.imagefiles.dng import as_shot_neutral, color_matrix, dng_bytes
    from illumix.service.encoding import meta_json

    spec = p.spec
    noise = p.noise
    black, white = dng_levels(noise)
    raw = arrays["raw"] if noise is not None else simulate_raw(arrays["raw"], DNG_LEVELS, noise=False)
    lib, grid = ctx.library, p.metas[0].spectral_grid
    sensor, skey = lib.sensor(p.sensor, grid)
    d65 = lib.illuminant("D65", grid)
    ccm, _ = lib.ccm(sensor, skey, *d65)
    lit = [i for i, r in enumerate(p.reads()) if r]
    wps = [meta["illuminants"][i]["white_point_rgb"] for i in lit]
    if not lit:
        neutral = [1.0, 1.0, 1.0]  # nothing lit: a black frame
    elif len(lit) == 1:
        neutral = as_shot_neutral(wps)
    else:
        neutral = as_shot_neutral(wps, arrays["mixture"][..., lit], arrays["mask"])
    meta["encoding"] = {"black_level": black, "white_level": white, "cfa": p.bayer, "as_shot_neutral": neutral}
    about = {k: meta[k] for k in ("scene", "view", "seed", "exposure_gain")} | {
        "illuminants": [(i["group"], i["illuminant"], i["intensity"]) for i in meta["illuminants"]],
        "ground_truth": meta["ground_truth"]["method"]}
    return dng_bytes(np.clip(np.round(raw), 0, white).astype(np.uint16), black=black, white=white,
                     pattern=p.bayer, matrix=color_matrix(sensor.weights(), d65[0], ccm), neutral=neutral,
                     model=spec.sensor, description="illumix GET /sample " + meta_json(about),
                     noise=noise_profile(noise) if noise is not None else None)


def encode_exr(p, arrays: dict[str, np.ndarray], meta: dict | None) -> bytes:
    """The OpenEXR of the sample's array outputs (module docstring); ``meta`` in ``illumixMeta`` when given."""
    from illumix.imagefiles.layered_exr import layered_exr_bytes
    from illumix.service.encoding import meta_json

    return layered_exr_bytes(arrays, groups=p.groups, wavelengths=p.metas[0].spectral_grid.wavelengths,
                             meta=None if meta is None else meta_json(meta))
