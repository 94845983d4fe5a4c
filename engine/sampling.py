"""Compose one sample from the store: resolve the request, price it, read (cached) cubes, run the physics.

Three steps, so a request is refused or queued *before* it costs anything:

- :func:`engine.plan.plan` resolves names, window and lighting from metadata only (no cube is read);
- :func:`price` bounds the bytes it will allocate (:mod:`engine.budget`);
- :func:`build` reads the cubes and composes → ``(arrays, meta)``: arrays named as in
  :data:`retarget.compose.OUTPUTS`, meta a JSON-able dict (scene/view/groups, illuminants with their
  sensor white points, intensities, CCMs, exposure gain, seeds, store and renderer provenance,
  timings).
"""

from __future__ import annotations

import time

import numpy as np

from illumix.engine import budget
from illumix.engine import extra_outputs as extra
from illumix.engine.context import Context
from illumix.engine.cubes import aov_key, cube_bytes, frame_bytes, plan_cube_key, projection_key, read_cube, whole_cube
from illumix.engine.plan import Plan, plan
from illumix.engine.sample_meta import sample_meta
from illumix.engine.spec import SPECTRAL_OUTPUTS, SampleSpec
from illumix.engine.torch_sampling import build_on_device
from illumix.engine.torch_sampling import refusal as torch_refusal
from illumix.retarget.compose import OUTPUTS as COMPOSED
from illumix.retarget.compose import compose
from illumix.retarget.errors import SpectralError
from illumix.retarget.finite import all_finite
from illumix.retarget.relight import band_scales, raw_weights
from illumix.retarget.sensor_model import mosaic, simulate_raw

__all__ = ["Plan", "build", "build_sample", "exposure_for", "group_inputs", "plan", "price", "unit_weights"]


def price(p: Plan, ctx: Context, encoded: bool = True) -> int:
    """Upper bound of the bytes :func:`build` (and encoding, when ``encoded``) will allocate.

    A decoded cube the cache holds is the cache's memory (bounded by ``--cache-mb``), not the
    request's; only a window of a cube too large for the cache is the request's own. A cube found
    in the cache here is held by the plan until :func:`build` uses it, so it cannot be evicted in
    between and decoded unpaid.
    """
    w, h = p.window[2:]
    bands = p.metas[0].n_bands
    cacheable = cube_bytes(p) <= ctx.cache.max_cost
    copies = to_read = 0
    for kind in ("transport", "illumination") if p.illumination else ("transport",):
        for g, lit in zip(p.groups, p.reads()):
            if not lit:
                continue
            cube = ctx.cache.lookup(plan_cube_key(p, g, kind), count=False) if cacheable else None
            if cube is not None:
                p.held[(g, kind)] = cube
                continue
            to_read += 1
            copies += not cacheable
    read_w = p.full[0] if cacheable else w  # a cacheable cube is decoded whole
    return budget.sample_bytes(window=(w, h), read_width=read_w, out_size=p.out_size, bands=bands,
                               window_copies=copies, groups_to_read=to_read, n_groups=len(p.groups),
                               outputs=p.spec.array_outputs(), noise=p.spec.noise is not None, encoded=encoded,
                               physical=p.illumination and p.gt == "physical")


def _resizer(out_w: int, out_h: int, w: int, h: int):
    if (out_w, out_h) == (w, h):
        return None

    def resize(group_raw: np.ndarray) -> np.ndarray:
        return np.stack([extra.resize_image(g, out_w, out_h) for g in group_raw])

    return resize


def unit_weights(spd: np.ndarray, emission: np.ndarray, group: str, sensor, grid) -> np.ndarray:
    """A group's ``(B, 3)`` relight + projection weights at intensity 1 (the weights a cached
    projection is computed with; :func:`retarget.relight.raw_weights`)."""
    scales = band_scales(np.asarray(spd)[None], np.asarray(emission, np.float64)[None], np.ones(1), [group],
                         grid.wavelengths)
    return raw_weights(scales, sensor.weights())[0]


def _checked_ccms(p: Plan, lib, sensor, skey: str, spds, ikeys, wanted: bool) -> tuple[list | None, list]:
    """``(the groups' CCMs, or None unless ``wanted``; per group its Conditioning, or None if not fitted)``.

    Every lit group's sensor × illuminant is checked against the bounds of :mod:`retarget.conditioning`
    (:meth:`engine.library.Library.ccm` refuses a degenerate one) whatever the outputs, so the raw of a
    degenerate pair is refused like its CCM. A group at intensity 0 is checked only when its CCM is
    served (``wanted``: then a degenerate one is refused, never served): an illuminant it does not
    light cannot spoil a raw-only sample. A fit costs ~1 ms once, then it is cached per pair."""
    fits = [lib.ccm(sensor, skey, s, k, n or "E") if wanted or a > 0 else (None, None)
            for s, k, n, a in zip(spds, ikeys, p.names, p.intensities)]
    return ([m for m, _ in fits] if wanted else None), [q for _, q in fits]


def group_inputs(ctx: Context, p: Plan, kind: str, unit: list[np.ndarray | None], keys: list[tuple]) -> list:
    """Per group what :func:`retarget.compose.compose` projects: zeros for a group not read, else the
    window of the frame's cached projection (:mod:`engine.projections`) or of the cube itself.

    unit : per group the :func:`unit_weights` (``None``: do not use projections, e.g. when spectral
    outputs need the cube's bands); keys : per group ``(sensor key, illuminant key)``."""
    w, h = p.window[2:]
    zero = np.broadcast_to(np.float32(0), (h, w, p.metas[0].n_bands))
    whole = (w, h) == p.full
    frame = frame_bytes(p)
    proj = ctx.projections if cube_bytes(p) <= ctx.cache.max_cost else None
    out = []
    for i, (g, r) in enumerate(zip(p.groups, p.reads())):
        if not r:
            out.append(zero)
            continue
        win = None
        if proj is not None and unit[i] is not None:
            win = proj.window(projection_key(p, g, kind, *keys[i]), lambda g=g: whole_cube(ctx, p, g, kind),
                              unit[i], p.window, frame, whole)
        out.append(win if win is not None else read_cube(ctx, p, g, kind))
    return out


def _aov_reader(ctx: Context, p: Plan):
    """``name → crop of the view's AOV`` (``None`` when the view has none of that name).

    The whole AOV is kept in the LRU cache: every request reads the ``mask`` and ``emitter`` AOVs
    for its validity, and decoding them from the store cost ~10 ms of a 256² crop's ~28 ms. A view
    is re-rendered with its cubes, so the cubes' render stamps name the AOVs' version too.
    """
    stamp = tuple(p.stamps)
    x, y, w, h = p.window

    def read(name: str) -> np.ndarray | None:
        if name not in p.aovs:
            return None
        full = ctx.cache.get(aov_key(p.scene, p.view, name, stamp),
                             lambda: ctx.store.read_aov(p.scene, p.view, name))
        return full[y:y + h, x:x + w]
    return read


def exposure_for(spec: SampleSpec) -> float | str | None:
    """The exposure to apply: as asked, else auto for a PNG or DNG of raw (1.0 = its white level)."""
    value = spec.exposure_value()
    if value is None and spec.format in ("png", "dng") and "raw" in spec.outputs:
        return "constant"
    return value


def build(p: Plan, ctx: Context, keep_device: bool = False) -> tuple[dict[str, np.ndarray], dict]:
    """Read and compose the planned sample: on ``ctx.torch``'s device where it can
    (:mod:`engine.torch_sampling`; ``keep_device``: return its tensors there), else with numpy."""
    t0 = time.perf_counter()
    spec, lib = p.spec, ctx.library
    grid = p.metas[0].spectral_grid
    sensor, skey = lib.sensor(p.sensor, grid)
    spds, ikeys = zip(*(lib.illuminant(n or "E", grid) for n in p.names))
    served = bool({"ccm", "srgb", "meta"} & set(spec.outputs))  # outputs that use (or state) the CCMs
    ccms, quality = _checked_ccms(p, lib, sensor, skey, spds, ikeys, served)
    emissions = np.stack([np.asarray(m.emission, dtype=np.float64) for m in p.metas])
    want = set(spec.array_outputs())
    on_device = ctx.torch is not None and torch_refusal(spec) is None
    unit = [None] * len(p.groups)
    if on_device or (ctx.projections is not None and not (want & SPECTRAL_OUTPUTS)):
        unit = [unit_weights(s, e, g, sensor, grid) if r else None
                for s, e, g, r in zip(spds, emissions, p.groups, p.reads())]
    t_setup = time.perf_counter()
    w, h = p.window[2:]
    aov = _aov_reader(ctx, p)
    valid, reasons = extra.view_validity(aov, *p.out_size)
    if on_device:
        try:
            return build_on_device(p, ctx, unit, sensor, spds, ccms, quality, valid, reasons, keep_device, t0, t_setup)
        except Exception as exc:
            if keep_device or not ctx.torch.out_of_memory(exc):
                raise
            ctx.torch.cubes.clear()  # the device is full: free its cubes, compose this one on the CPU
    keys = [(skey, k) for k in ikeys]
    cubes = group_inputs(ctx, p, "transport", unit, keys)
    illum = group_inputs(ctx, p, "illumination", unit, keys) if p.illumination else None
    t_read = time.perf_counter()
    exposure = exposure_for(spec)
    comp = compose(cubes, emissions=emissions, illuminants=np.stack(spds), intensities=np.array(p.intensities),
                   sensor=sensor, ccms=None if ccms is None else np.stack(ccms), outputs=(want & set(COMPOSED)) | ({"raw"} if spec.noise else set()),
                   exposure=exposure, group_names=p.groups, resize=_resizer(*p.out_size, w, h),
                   illumination=illum if p.gt == "physical" and illum is not None else None, valid=valid)
    arrays = {k: v for k, v in comp.outputs().items() if k in want}
    arrays |= extra.aov_outputs(aov, want, *p.out_size)
    if want & SPECTRAL_OUTPUTS:
        scales = band_scales(np.stack(spds), emissions, np.array(p.intensities), p.groups, grid.wavelengths)
        arrays |= extra.spectral_outputs(cubes, illum, scales, want, *p.out_size)
    del cubes, illum
    for k, a in arrays.items():
        if not all_finite(a):
            raise SpectralError(f"the composed {k} overflows float32 (intensities × exposure × the stored "
                                "radiance is too large); lower intensities= or exposure=")
    noise = p.noise
    if noise is not None and "raw" in want:
        arrays["raw"] = simulate_raw(arrays["raw"], noise, seed=p.seed)
    if p.bayer and "raw" in want:
        arrays["raw"] = mosaic(arrays["raw"], p.bayer)
    t_compose = time.perf_counter()
    meta = sample_meta(p, sensor, comp.white_points, ccms, quality, comp.mask, valid, reasons, comp.exposure_gain,
                       noise, {"setup": 1e3 * (t_setup - t0), "read": 1e3 * (t_read - t_setup),
                               "compose": 1e3 * (t_compose - t_read)})
    if comp.srgb is not None:
        meta["srgb_exposure"] = comp.srgb_exposure  # what the sRGB rendering applied on top of raw
    return arrays, meta


def build_sample(spec: SampleSpec, ctx: Context) -> tuple[dict[str, np.ndarray], dict]:
    """:func:`plan` then :func:`build`, without admission (for in-process use and benchmarks)."""
    return build(plan(spec, ctx), ctx)
