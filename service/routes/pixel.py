"""``GET /explore/pixel``: the spectra at one pixel of a frame, for the web explorer's hover chart.

Takes the ``GET /explore/frame`` parameters (scene, view, sensor, illuminants or pair, intensities,
crop, size, denoise, seed) plus ``x``, ``y`` — a pixel of that frame — and answers per light group
the relit spectra there, composed as ``GET /sample`` composes (:mod:`retarget.relight`)::

    radiance_g(λ_i)     = a_g Φ̄_g(λ_i) / Ē_g(λ_i) · T_g(x, y, λ_i)     the light group g sends to the camera
    illumination_g(λ_i) = a_g Φ̄_g(λ_i) / Ē_g(λ_i) · U_g(x, y, λ_i)     what a white Lambertian surface there would
    raw_g[k]            = Σ_i C_k(λ_i) Δλ · radiance_g(λ_i)              the group's camera raw (relative, as /explore/frame)

and their sums over the groups, with ``reflectance = Σ T / Σ U`` (where ``U > 0``; the first hit's
diffuse reflectance, ``extra_outputs.spectral_outputs``). Units are the renderer's radiometric
units relative to the SPDs' normalisation — the frame's raw (no exposure) is ``total.raw_rgb``.

Cheap: only the chunks the pixel's footprint overlaps are read (``CubeStore.read_cube(crop=…)``),
or the pixel is sliced from a cube the decoded-cube cache already holds. A resized frame's pixel
covers several view pixels: the spectra are their mean over the footprint rounded outward to whole
pixels (exact for integer factors; ``area_weighted: false`` says when the frame's own resampling
weights the edges differently).
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Query
from pydantic import BaseModel, Field, WithJsonSchema

from illumix.engine import extra_outputs as extra
from illumix.engine.cubes import plan_cube_key
from illumix.engine.sampling import plan
from illumix.retarget.relight import band_scales
from illumix.service.deps import CtxDep
from illumix.service.errors import error_responses, fail, refuses
from illumix.service.routes.explore import _FIXED_SCHEMA, FIXED, FrameSpec

router = APIRouter(prefix="/explore", tags=["explore"])
#: what the spectra do not depend on, or that /explore/frame fixes: refused with a hint
PIXEL_FIXED = (*FIXED, "exposure", "gt")


class PixelSpec(FrameSpec):
    """The ``GET /explore/frame`` parameters and the pixel; exposure and gt are refused (the spectra
    depend on neither)."""

    x: int = Field(..., ge=0, le=10**6, examples=[0], description="column of the frame's pixel (0 = left)")
    y: int = Field(..., ge=0, le=10**6, examples=[0], description="row of the frame's pixel (0 = top)")
    exposure: Annotated[str | None, WithJsonSchema(_FIXED_SCHEMA)] = Field(None, max_length=32)
    gt: Annotated[str | None, WithJsonSchema(_FIXED_SCHEMA)] = Field(None, max_length=32)


class GroupSpectrum(BaseModel):
    group: str
    illuminant: str | None = Field(description="the illuminant lighting it (None: off)")
    intensity: float
    radiance: list[float] = Field(description="relit transport a·Φ̄/Ē·T at the pixel, per band")
    illumination: list[float] | None = Field(description="relit illumination a·Φ̄/Ē·U (None: no illumination cube)")
    raw_rgb: list[float] = Field(description="the group's camera raw (relative units, as /explore/frame's raw)")


class TotalSpectrum(BaseModel):
    radiance: list[float]
    illumination: list[float] | None
    raw_rgb: list[float]
    reflectance: list[float] | None = Field(description="Σ T / Σ U over the groups (0 where U is 0; None without "
                                                        "illumination cubes)")


class PixelSpectra(BaseModel):
    scene: str
    view: str
    sensor: str
    x: int
    y: int
    footprint: list[int] = Field(description="x, y, w, h: the view pixels averaged (the frame pixel's area)")
    area_weighted: bool = Field(description="true when the footprint is exactly the frame pixel's area")
    valid: bool | None = Field(description="the frame's mask there (geometry hit, not a light's surface); None: "
                                           "the view stores no mask")
    denoise: str
    wavelengths: list[float]
    groups: list[GroupSpectrum]
    total: TotalSpectrum


@router.get("/pixel", response_model=PixelSpectra, responses=error_responses(404, 413, 422, 503))
@refuses(*PIXEL_FIXED)
def pixel(params: Annotated[PixelSpec, Query()], ctx: CtxDep) -> PixelSpectra:
    """The spectra at pixel (x, y) of the frame ``GET /explore/frame`` gives for the same parameters:
    per light group the radiance it sends to the camera and the illumination it gives, relit to the
    request's illuminants, their sum, the reflectance, and each group's camera raw."""
    given = [f for f in PIXEL_FIXED if f in params.model_fields_set]
    if given:
        raise fail(422, f"/explore/pixel gives spectra, which do not depend on {', '.join(given)}; drop it",
                   loc=["query", given[0]])
    p = plan(params.model_copy(update={"outputs": ["raw"], "format": "arrays"}), ctx)
    out_w, out_h = p.out_size
    for name, v, n in (("x", params.x, out_w), ("y", params.y, out_h)):
        if v >= n:
            raise fail(422, f"{name}={v} is outside the {out_w}x{out_h} frame of {p.scene}/{p.view}: give {name} in "
                       f"0..{n - 1}", loc=["query", name])
    win, exact = footprint(p.window, p.out_size, params.x, params.y)
    grid = p.metas[0].spectral_grid
    lib = ctx.library
    sensor, skey = lib.sensor(p.sensor, grid)
    spds, ikeys = zip(*(lib.illuminant(n or "E", grid) for n in p.names))
    for s, k, n, a in zip(spds, ikeys, p.names, p.intensities):
        if a > 0:  # the pairs /sample refuses (retarget.conditioning) are refused here too
            lib.ccm(sensor, skey, s, k, n or "E")
    emissions = np.stack([np.asarray(m.emission, np.float64) for m in p.metas])
    scales = band_scales(np.stack(spds), emissions, np.array(p.intensities), p.groups, grid.wavelengths)
    with_u = all(m.illumination is not None and m.illumination.storage is not None
                 for m, r in zip(p.metas, p.reads()) if r)
    kinds = ("transport", "illumination") if with_u else ("transport",)
    bands = p.metas[0].n_bands
    hold = ctx.memory.acquire(win[2] * win[3] * bands * 4 * len(p.groups) * len(kinds) * 2,
                              f"the spectra of pixel {params.x},{params.y}")
    try:
        means = {k: np.stack([_mean(ctx, p, g, k, win) if r else np.zeros(bands)
                              for g, r in zip(p.groups, p.reads())]) for k in kinds}
        valid = _valid(ctx, p, win)
    finally:
        hold.release()
    weights = sensor.weights()  # (bands, 3): C_k(λ_i) Δλ
    rad = scales * means["transport"]
    ill = scales * means["illumination"] if with_u else None
    groups = [GroupSpectrum(group=g, illuminant=n, intensity=a, radiance=_list(rad[i]),
                            illumination=None if ill is None else _list(ill[i]), raw_rgb=_list(rad[i] @ weights))
              for i, (g, n, a) in enumerate(zip(p.groups, p.names, p.intensities))]
    refl = None
    if with_u:
        t, u = means["transport"].sum(0), means["illumination"].sum(0)
        refl = _list(np.divide(t, u, out=np.zeros_like(t), where=u > 0))
    total = TotalSpectrum(radiance=_list(rad.sum(0)), illumination=None if ill is None else _list(ill.sum(0)),
                          raw_rgb=_list(rad.sum(0) @ weights), reflectance=refl)
    return PixelSpectra(scene=p.scene, view=p.view, sensor=sensor.name, x=params.x, y=params.y, footprint=list(win),
                        area_weighted=exact, valid=valid, denoise=p.denoise, wavelengths=grid.wavelengths.tolist(),
                        groups=groups, total=total)


def footprint(window: tuple[int, int, int, int], out_size: tuple[int, int], x: int, y: int
              ) -> tuple[tuple[int, int, int, int], bool]:
    """``((x, y, w, h) of the view pixels frame pixel (x, y) covers, rounded outward; exact)``: the
    frame is the crop ``window`` resampled to ``out_size``. ``exact``: the footprint is whole pixels
    (the frame's area resampling averages exactly these, with equal weights)."""
    cx, cy, cw, ch = window
    ow, oh = out_size
    x0, x1 = math.floor(x * cw / ow), math.ceil((x + 1) * cw / ow)
    y0, y1 = math.floor(y * ch / oh), math.ceil((y + 1) * ch / oh)
    exact = (cw % ow == 0 and ch % oh == 0) or (ow >= cw and oh >= ch)
    if ow > cw or oh > ch:  # enlarged: the frame interpolates; the nearest view pixel stands for it
        x0 = min(cw - 1, int((x + 0.5) * cw / ow))
        y0 = min(ch - 1, int((y + 0.5) * ch / oh))
        x1, y1, exact = x0 + 1, y0 + 1, (ow, oh) == (cw, ch)
    return (cx + x0, cy + y0, x1 - x0, y1 - y0), exact


def _mean(ctx, p, group: str, kind: str, win) -> np.ndarray:
    """The mean spectrum ``(bands,)`` float64 of a group's ``kind`` cube over ``win``: sliced from the
    decoded-cube cache when it holds the cube, else only the chunks ``win`` overlaps are read."""
    x, y, w, h = win
    cube = ctx.cache.lookup(plan_cube_key(p, group, kind), count=False)
    if cube is None:
        block = ctx.store.read_cube(p.scene, p.view, group, crop=win, kind=kind, denoised=p.denoise != "none")
    else:
        block = cube[y:y + h, x:x + w]
    return block.reshape(-1, block.shape[-1]).mean(0, dtype=np.float64)


def _valid(ctx, p, win) -> bool | None:
    """The frame's validity (:func:`engine.extra_outputs.view_validity`) over the footprint."""
    def read(name: str):
        return ctx.store.read_aov(p.scene, p.view, name, crop=win) if name in p.aovs else None
    valid, _ = extra.view_validity(read, 1, 1)
    return None if valid is None else bool(valid[0, 0])


def _list(a: np.ndarray) -> list[float]:
    """Seven significant digits (the cubes are float32 or float16): a short answer, no precision lost."""
    return [float(f"{v:.7g}") for v in np.asarray(a, np.float64)]
