"""``/explore/*``: what the web explorer (:mod:`service.routes.web`) shows, one request per update.

- ``GET /explore/frame`` — the ``GET /sample`` parameters; one ``arrays`` container with what the page
  draws: ``raw``, ``gain``, ``illum``, ``mixture`` (float32), ``mask`` (bool), and two display-ready
  sRGB images as uint8 ``(H, W, 3)``: ``srgb`` (the pixel-wise ground truth) and ``baseline`` (the same
  frame white-balanced by one global white point, :mod:`retarget.global_wb`, at the same exposure);
  ``meta`` as ``/sample``'s, plus ``meta["baseline"]``. outputs, format, dtype and bayer are fixed.
- ``GET /explore/spectra`` — the curves to plot: the sensor's sensitivities, each illuminant's SPD and
  sensor white point, and the Planckian and daylight loci in the sensor's r/g, b/g
  (:mod:`retarget.locus`), on the default spectral grid.
"""

from __future__ import annotations

import time
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Query
from fastapi.responses import Response
from pydantic import BaseModel, ConfigDict, Field, WithJsonSchema, field_validator

from illumix.engine.sampling import build, plan, price
from illumix.engine.spec import DEFAULT_OUTPUTS, MAX_NAME, Outputs, SampleSpec
from illumix.retarget import global_wb
from illumix.retarget.grid import DEFAULT_GRID
from illumix.retarget.groundtruth import white_point
from illumix.retarget.locus import locus
from illumix.service import arrays_format
from illumix.service.deps import CtxDep
from illumix.service.errors import error_responses, fail, refuses
from illumix.service.models import IlluminantCurve, LocusPoint, Spectra
from illumix.service.routes.samples import HeldResponse

router = APIRouter(prefix="/explore", tags=["explore"])
#: what a frame is composed with (meta carries each group's white point and CCM for the baseline)
FRAME_OUTPUTS = ("raw", "gain", "srgb", "mixture", "illum", "mask", "meta")
SENT = ("raw", "gain", "illum", "mixture", "mask")  # sent as composed; srgb and baseline as uint8
FIXED = ("outputs", "format", "dtype", "bayer", "noise")  # noise: the baseline renders the clean raw
BASELINE_DEFINITION = ("one white point for the whole frame: the groups' sensor white points weighted by their "
                       "mean mixture share over valid pixels (thesis §5.2), with the CCMs weighted alike and "
                       "the ground-truth rendering's exposure")


_FIXED_SCHEMA = {"not": {}, "description": "fixed by /explore/frame: refused here (GET /sample takes it)"}


class FrameSpec(SampleSpec):
    """The ``GET /sample`` parameters; those the frame fixes (:data:`FIXED`) are declared unacceptable
    in the OpenAPI schema (``not: {}``) and refused by :func:`frame` with a hint, validated as before."""

    outputs: Annotated[Outputs, WithJsonSchema(_FIXED_SCHEMA)] = Field(default_factory=lambda: list(DEFAULT_OUTPUTS))
    # default_factory: a plain default would be stated in the schema, though no value is acceptable here
    format: Annotated[Literal["npz", "arrays", "png", "tiff", "dng", "exr"], WithJsonSchema(_FIXED_SCHEMA)] = Field(
        default_factory=lambda: "npz")
    dtype: Annotated[Literal["float32", "float16"], WithJsonSchema(_FIXED_SCHEMA)] = Field(
        default_factory=lambda: "float32")
    noise: Annotated[str | None, WithJsonSchema(_FIXED_SCHEMA)] = Field(None, max_length=512)
    bayer: Annotated[str | None, WithJsonSchema(_FIXED_SCHEMA)] = None


@router.get("/frame", response_class=Response,
            responses={200: {"content": {arrays_format.MEDIA_TYPE: {"schema": {"type": "string", "format": "binary"}}},
                             "description": "arrays container: raw, gain, illum, mixture (float32), mask (bool), "
                                            "srgb and baseline (uint8 sRGB), meta with meta.baseline"},
                       **error_responses(404, 413, 422, 503)})
@refuses(*FIXED)
def frame(params: Annotated[FrameSpec, Query()], ctx: CtxDep) -> Response:
    """One update of the web explorer: the sample, its pixel-wise ground-truth sRGB rendering and the
    single-global-white-point baseline. Takes the ``GET /sample`` parameters but outputs, format,
    dtype, bayer and noise (the page needs these fixed; a noisy raw is in digital numbers, which the
    baseline's exposure would not match). ``Server-Timing`` says where the time went (ms):
    ``compose`` (the sample), ``baseline`` (with the uint8 images and the encoding), ``total`` (from the
    request to the encoded body, before sending)."""
    t0 = time.perf_counter()
    given = [f for f in FIXED if f in params.model_fields_set]
    if given:
        raise fail(422, f"/explore/frame sends fixed outputs; drop {', '.join(given)} (use /sample to choose them)",
                   loc=["query", given[0]])
    spec = params.model_copy(update={"outputs": list(FRAME_OUTPUTS), "format": "arrays"})
    p = plan(spec, ctx)
    w, h = p.out_size
    # beyond /sample's price (which covers the ground truth's sRGB): the baseline's rendering (the
    # white-balanced and the CCM'd copies plus encode_srgb's three float32 temporaries) and two
    # uint8 images — at most ~66 bytes a pixel alive at once
    extra = w * h * 3 * (4 * 5 + 2)
    hold = ctx.memory.acquire(price(p, ctx) + extra, f"this explorer frame ({w}x{h})")
    try:
        t1 = time.perf_counter()
        arrays, meta = build(p, ctx)
        t2 = time.perf_counter()
        meta["baseline"] = _baseline(arrays, meta)
        out = {k: arrays[k] for k in SENT}
        out["srgb"] = _bytes(arrays["srgb"])
        out["baseline"] = _bytes(meta["baseline"].pop("image"))
        del arrays
        body = arrays_format.encode(out, meta=meta)
        t3 = time.perf_counter()
        timing = f"compose;dur={1e3 * (t2 - t1):.1f}, baseline;dur={1e3 * (t3 - t2):.1f}, total;dur={1e3 * (t3 - t0):.1f}"
        return HeldResponse(body, hold, media_type=arrays_format.MEDIA_TYPE, headers={"Server-Timing": timing})
    except BaseException:
        hold.release()
        raise


def _baseline(arrays: dict[str, np.ndarray], meta: dict) -> dict:
    """The single-global-white-point rendering and its parameters (``image``: float32 sRGB)."""
    groups = meta["illuminants"]
    shares = global_wb.frame_shares(arrays["mixture"], arrays["mask"])
    wps = np.array([g["white_point_rgb"] for g in groups])
    ccm = global_wb.global_ccm(shares, np.array([g["ccm"] for g in groups]))
    wp = global_wb.global_white_point(shares, wps)
    raw = arrays["raw"]
    exposure = meta["srgb_exposure"]  # the ground truth's sRGB rendering's own (retarget.compose)
    return {"white_point_rgb": wp.tolist(), "ccm": ccm.round(8).tolist(), "exposure": exposure,
            "shares": {g["group"]: float(s) for g, s in zip(groups, shares)}, "definition": BASELINE_DEFINITION,
            "image": global_wb.render_global(raw, wp, ccm, exposure)}


def _bytes(srgb: np.ndarray) -> np.ndarray:
    """sRGB in [0, 1] → uint8 0..255 (rounded), ready for a canvas."""
    return (np.clip(srgb, 0, 1) * np.float32(255) + np.float32(0.5)).astype(np.uint8)


class SpectraQuery(BaseModel):
    """``GET /explore/spectra`` parameters."""

    model_config = ConfigDict(extra="forbid")
    sensor: str = Field("XYZ", min_length=1, max_length=MAX_NAME, examples=["XYZ"],
                        description="built-in or uploaded sensor name")
    illuminants: str = Field("", max_length=16 * MAX_NAME, examples=["A,D65"],
                             description="comma-separated illuminant names (registry, blackbody:K, daylight:K, "
                                         "uploads), e.g. A,D65")

    @field_validator("illuminants")
    @classmethod
    def _names(cls, v: str) -> str:
        if len([x for x in v.split(",") if x.strip()]) > 16:
            raise ValueError("illuminants: at most 16 names")
        return v

    def names(self) -> list[str]:
        return [x.strip() for x in self.illuminants.split(",") if x.strip()]


@router.get("/spectra", response_model=Spectra, responses=error_responses(404, 422))
def spectra(q: Annotated[SpectraQuery, Query()], ctx: CtxDep) -> Spectra:
    """The sensor's sensitivities, the illuminants' SPDs (peak 1) with their white points on the
    sensor, and the Planckian and daylight loci in the sensor's r/g, b/g — on the default grid."""
    grid = DEFAULT_GRID
    sensor, _ = ctx.library.sensor(q.sensor, grid)
    curves = []
    for name in q.names():
        spd, _ = ctx.library.illuminant(name, grid)
        wp = white_point(sensor.weights(), spd, what=f"illuminant {name!r}")
        curves.append(IlluminantCurve(name=name, spd=(spd / spd.max()).round(6).tolist(),
                                      white_point_rgb=wp.tolist(), r_over_g=wp[0], b_over_g=wp[2]))
    loci = {kind: [LocusPoint(kelvin=k, r_over_g=wp[0], b_over_g=wp[2])
                   for k, wp in zip(*locus(sensor.weights(), grid, kind))] for kind in ("blackbody", "daylight")}
    return Spectra(sensor=sensor.name, grid=grid.to_dict(), wavelengths=grid.wavelengths.tolist(),
                   sensitivities=sensor.sensitivities.round(8).tolist(), illuminants=curves,
                   planckian=loci["blackbody"], daylight=loci["daylight"])
