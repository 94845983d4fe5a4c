"""Compose one sample from the store: resolve the request, price it, read (cached) cubes, run the physics.

Three steps, so a request is refused or queued *before* it costs anything:

- :func:`plan` resolves names, window and lighting from metadata only (no cube is read);
- :func:`price` bounds the bytes it will allocate (:mod:`service.budget`);
- :func:`build` reads the cubes and composes → ``(arrays, meta)``: arrays named as in
  :data:`retarget.compose.OUTPUTS`, meta a JSON-able dict (scene/view/groups, illuminants with their
  sensor white points, intensities, CCMs, exposure gain, seeds, store and renderer provenance,
  timings).
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from retarget.compose import GT_OUTPUTS, compose
from retarget.compose import OUTPUTS as COMPOSED
from retarget.errors import SpectralError, unknown_name
from retarget.finite import all_finite
from retarget.relight import band_scales, raw_weights
from retarget.sensor_model import mosaic, simulate_raw
from service import budget
from service import extra_outputs as extra
from service.context import Context, make_context  # noqa: F401 - re-exported
from service.errors import NotFound, fail
from service.limits import Limits
from service.sample_meta import sample_meta
from service.spec import SPECTRAL_OUTPUTS, SampleSpec
from service.torch_sampling import build_on_device
from service.torch_sampling import refusal as torch_refusal


@dataclass
class Plan:
    """A resolved request: everything but the pixels."""

    spec: SampleSpec
    seed: int
    scene: str
    view: str
    groups: list[str]
    metas: list = field(repr=False)
    names: list[str | None] = field(default_factory=list)
    intensities: list[float] = field(default_factory=list)
    window: tuple[int, int, int, int] = (0, 0, 0, 0)
    full: tuple[int, int] = (0, 0)
    out_size: tuple[int, int] = (0, 0)
    gt: str = "formula"
    gt_why: str = ""
    illumination: bool = False  # the illumination cubes are read (physical GT or spectral outputs)
    held: dict = field(default_factory=dict, repr=False)  # (group, kind) → cached cube, kept from price to build
    aovs: list[str] = field(default_factory=list)  # the view's stored AOVs
    denoise: str = "none"  # the denoise method whose stored copies are read ("none": the raw cubes)
    denoise_why: str = ""

    def reads(self) -> list[bool]:
        """Per group: whether its cube window is read (lit and not recorded empty)."""
        return [a > 0 and not m.empty for a, m in zip(self.intensities, self.metas)]


def _pick(kind: str, name: str | None, options: Callable[[], list[str]], exists: Callable[[str], bool],
          rng: random.Random) -> str:
    """The named scene or view, or one drawn by ``rng``. ``exists`` tests a name without listing them
    all (a request naming one of thousands of scenes reads one file); ``options`` lists them, only to
    draw one or to suggest close matches for an unknown name."""
    if name is not None and exists(name):
        return name
    known = options()
    if not known:
        raise NotFound(f"the store has no {kind}s; render some with `illumix render`")
    if name is None:
        return rng.choice(sorted(known))
    raise NotFound(str(unknown_name(kind, name, known)))


def _lighting(spec: SampleSpec, groups: list[str], rendered_as: list[str]) -> tuple[list[str | None], list[float]]:
    """Illuminant name per group (``None`` = off) and intensities. Without pair=/illuminants=, each
    group is lit as it was rendered: D65 for flat-emission cubes, else the cube's own emission."""
    if spec.pair is not None and spec.illuminants is not None:
        raise SpectralError("give either pair= or illuminants=, not both")
    if spec.pair is not None:
        if len(spec.pair) != 2:
            raise SpectralError(f"pair needs exactly two illuminants, e.g. pair=A,D65; got {spec.pair}")
        if len(groups) < 2:
            raise SpectralError(f"pair= needs a view with two light groups; this view has {groups}; "
                                "use illuminants= with one entry")
        names: list[str | None] = [*spec.pair] + [None] * (len(groups) - 2)
    elif spec.illuminants is not None:
        if len(spec.illuminants) != len(groups):
            raise SpectralError(f"illuminants= needs one entry per light group {groups} "
                                f"({len(groups)}), got {len(spec.illuminants)}")
        names = list(spec.illuminants)
    else:
        names = ["D65" if r == "flat" else r for r in rendered_as]
    intens = spec.intensities
    if intens is None:
        intens = [1.0 if n is not None else 0.0 for n in names]
    else:
        lit = [i for i, n in enumerate(names) if n is not None]
        if len(intens) == len(lit) and len(intens) != len(names):
            full = [0.0] * len(names)
            for i, v in zip(lit, intens):
                full[i] = v
            intens = full
        if len(intens) != len(names):
            raise SpectralError(f"intensities= needs one value per lit group ({len(lit)}), got {len(intens)}")
    return names, [float(a) for a in intens]


def _window(spec: SampleSpec, width: int, height: int, limits: Limits) -> tuple[tuple[int, int, int, int], tuple[int, int]]:
    x, y, w, h = spec.crop if spec.crop else (0, 0, width, height)
    if x + w > width or y + h > height:
        raise SpectralError(f"crop {x},{y},{w},{h} exceeds the view's {width}x{height} frame")
    out_w, out_h = spec.size if spec.size else (w, h)
    if max(out_w, out_h) > limits.max_side or out_w * out_h > limits.max_pixels:
        raise fail(413, f"output {out_w}x{out_h} exceeds the limits (side <= {limits.max_side}, "
                        f"pixels <= {limits.max_pixels}); crop or resize smaller", code="too_large")
    return (x, y, w, h), (out_w, out_h)


def plan(spec: SampleSpec, ctx: Context) -> Plan:
    """Resolve a request from metadata (no cube read). Raises 404/413/422 errors."""
    seed = spec.seed if spec.seed is not None else random.SystemRandom().randrange(2**31)
    rng = random.Random(seed)
    store = ctx.store
    scene = _pick("scene", spec.scene, store.scenes, store.has_scene, rng)
    view = _pick("view", spec.view, lambda: store.views(scene), lambda v: store.has_view(scene, v), rng)
    groups = store.groups(scene, view)
    if not groups:
        raise NotFound(f"view {scene}/{view} has no complete light groups yet; finish rendering it")
    metas = [store.cube_meta(scene, view, g) for g in groups]
    names, intensities = _lighting(spec, groups, [m.emission_name for m in metas])
    if len([n for n in names if n]) > ctx.limits.max_groups:
        raise SpectralError(f"at most {ctx.limits.max_groups} illuminants per request")
    vmeta = store.view_meta(scene, view)
    window, out_size = _window(spec, vmeta.width, vmeta.height, ctx.limits)
    if any(m.spectral_grid != metas[0].spectral_grid for m in metas):
        raise SpectralError(f"view {scene}/{view}: light groups are on different spectral grids; re-render")
    p = Plan(spec, seed, scene, view, groups, metas, names, intensities, window, (vmeta.width, vmeta.height), out_size,
             aovs=list(vmeta.aovs))
    p.gt, p.gt_why = _ground_truth(spec, p)
    p.denoise, p.denoise_why = _denoising(spec, p)
    wanted = set(spec.outputs)
    p.illumination = bool(SPECTRAL_OUTPUTS & wanted) or (p.gt == "physical" and bool(PHYSICAL_OUTPUTS & wanted))
    return p


# Outputs the physical ground truth changes (the formula's weights are eq. 3.3's whatever gt is).
PHYSICAL_OUTPUTS = GT_OUTPUTS - {"weights"}


def _ground_truth(spec: SampleSpec, p: Plan) -> tuple[str, str]:
    """``(method, why)``: physical wherever every lit group has its illumination cube, else formula."""
    missing = [g for g, m, r in zip(p.groups, p.metas, p.reads()) if r and not _has_illumination(m)]
    wants_spectra = SPECTRAL_OUTPUTS & set(spec.outputs)
    if missing and (spec.gt == "physical" or wants_spectra):
        what = "gt=physical" if spec.gt == "physical" else f"outputs {', '.join(sorted(wants_spectra))}"
        raise SpectralError(f"{what} needs illumination cubes, which groups {missing} of {p.scene}/{p.view} do not "
                            "have (rendered before they existed); re-render them with `illumix render … --overwrite`, "
                            "or use gt=formula")
    if spec.gt == "formula":
        return "formula", "asked for (gt=formula)"
    if missing:
        return "formula", (f"groups {missing} have no illumination cubes (re-render them with `illumix render … "
                           "--overwrite` for the physical ground truth)")
    return "physical", "default: every lit group has its illumination cube"


def _denoising(spec: SampleSpec, p: Plan) -> tuple[str, str]:
    """``(method, why)``: the stored denoised copies named (or, by default, whichever every lit group
    has, when they agree), else ``"none"``."""
    if spec.denoise == "none":
        return "none", "asked for (denoise=none)"
    lit = [(g, m) for g, m, r in zip(p.groups, p.metas, p.reads()) if r]
    stored = {g: (m.denoised.method if m.denoised is not None and m.denoised.storage is not None else None)
              for g, m in lit}
    if spec.denoise is not None:
        lacking = [g for g, meth in stored.items() if meth != spec.denoise]
        if lacking:
            have = sorted({f"{meth or 'none'}" for meth in stored.values()})
            raise SpectralError(f"denoise={spec.denoise}: groups {lacking} of {p.scene}/{p.view} have no copies "
                                f"denoised with it (stored: {', '.join(have)}); re-render them with `illumix render … "
                                f"--denoise {spec.denoise} --overwrite`, or ask denoise=none")
        return spec.denoise, f"asked for (denoise={spec.denoise})"
    methods = set(stored.values())
    if not lit:
        return "none", "no group is lit"
    if None in methods:
        return "none", (f"groups {[g for g, m in stored.items() if m is None]} have no denoised copies (re-render "
                        "them with `illumix render … --overwrite` to store them)")
    if len(methods) > 1:
        return "none", f"the lit groups were denoised with different methods {sorted(methods)}; ask one by name"
    (method,) = methods
    return method, f"default: every lit group has copies denoised with {method}"


def _has_illumination(meta) -> bool:
    return meta.illumination is not None and meta.illumination.storage is not None


def cube_bytes(p: Plan) -> int:
    """Decoded bytes of one whole float32 cube of the plan's view."""
    return p.full[0] * p.full[1] * p.metas[0].n_bands * 4


def cube_key(scene: str, view: str, group: str, kind: str, denoise: str, created: str) -> tuple:
    """The cube cache's key of a decoded whole cube (public so ``serve --warm`` fills the same entries).
    ``created`` names the render: a cube re-rendered while the service runs is a new entry, so the
    transport and illumination cubes of one sample always come from the same render."""
    return (scene, view, group, kind, denoise, created)


def aov_key(scene: str, view: str, name: str, stamp: tuple) -> tuple:
    """The cube cache's key of a view's whole AOV; ``stamp``: the render stamps of all its groups' cubes."""
    return (scene, view, "aov", name, stamp)


def plan_cube_key(p: Plan, group: str, kind: str) -> tuple:
    """The cube cache's key of a group's ``kind`` cube in plan ``p`` (:func:`cube_key`)."""
    return cube_key(p.scene, p.view, group, kind, p.denoise, p.metas[p.groups.index(group)].created)


def projection_key(p: Plan, group: str, kind: str, skey, ikey) -> tuple:
    """The key of a group's whole-frame projection (:mod:`service.projections`) for a sensor and an
    illuminant key (:class:`service.library.Library`)."""
    return (plan_cube_key(p, group, kind), skey, ikey)


def frame_bytes(p: Plan) -> int:
    """Bytes of one whole-frame float32 camera-raw projection of the plan's view."""
    return p.full[0] * p.full[1] * 3 * 4


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


def whole_cube(ctx: Context, p: Plan, group: str, kind: str = "transport") -> np.ndarray:
    """The decoded whole cube from the LRU cache (decoded and kept on first use; held by the plan
    from :func:`price` on)."""
    cube = p.held.pop((group, kind), None)
    if cube is not None:
        ctx.cache.count_hit()  # found by price() without counting, used now
        return cube
    dn = p.denoise != "none"
    return ctx.cache.get(plan_cube_key(p, group, kind),
                         lambda: ctx.store.read_cube(p.scene, p.view, group, kind=kind, denoised=dn),
                         expected_cost=cube_bytes(p))


def read_cube(ctx: Context, p: Plan, group: str, kind: str = "transport") -> np.ndarray:
    """The window of a cube (``kind`` transport or illumination), sliced from the decoded whole cube in
    the LRU cache (so every later crop of it is a hit); a cube larger than the whole cache is read
    window by window, uncached."""
    x, y, w, h = p.window
    if cube_bytes(p) > ctx.cache.max_cost:
        return ctx.store.read_cube(p.scene, p.view, group, crop=p.window, kind=kind, denoised=p.denoise != "none")
    return whole_cube(ctx, p, group, kind)[y:y + h, x:x + w]


def unit_weights(spd: np.ndarray, emission: np.ndarray, group: str, sensor, grid) -> np.ndarray:
    """A group's ``(B, 3)`` relight + projection weights at intensity 1 (the weights a cached
    projection is computed with; :func:`retarget.relight.raw_weights`)."""
    scales = band_scales(np.asarray(spd)[None], np.asarray(emission, np.float64)[None], np.ones(1), [group],
                         grid.wavelengths)
    return raw_weights(scales, sensor.weights())[0]


def group_inputs(ctx: Context, p: Plan, kind: str, unit: list[np.ndarray | None], keys: list[tuple]) -> list:
    """Per group what :func:`retarget.compose.compose` projects: zeros for a group not read, else the
    window of the frame's cached projection (:mod:`service.projections`) or of the cube itself.

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
    stamp = tuple(m.created for m in p.metas)
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
    (:mod:`service.torch_sampling`; ``keep_device``: return its tensors there), else with numpy."""
    t0 = time.perf_counter()
    spec, lib = p.spec, ctx.library
    grid = p.metas[0].spectral_grid
    sensor, skey = lib.sensor(spec.sensor, grid)
    spds, ikeys = zip(*(lib.illuminant(n or "E", grid) for n in p.names))
    # a CCM fit (~1 ms, then cached per sensor and illuminant) only when an output or the metadata uses it
    if {"ccm", "srgb", "meta"} & set(spec.outputs):
        ccms, fit_de = zip(*(lib.ccm(sensor, skey, s, k) for s, k in zip(spds, ikeys)))
    else:
        ccms, fit_de = None, [None] * len(spds)
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
            return build_on_device(p, ctx, unit, sensor, spds, ccms, fit_de, valid, reasons, keep_device, t0, t_setup)
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
    noise = spec.noise_model()
    if noise is not None and "raw" in want:
        arrays["raw"] = simulate_raw(arrays["raw"], noise, seed=p.seed)
    if spec.bayer and "raw" in want:
        arrays["raw"] = mosaic(arrays["raw"], spec.bayer)
    t_compose = time.perf_counter()
    meta = sample_meta(p, sensor, comp.white_points, ccms, fit_de, comp.mask, valid, reasons, comp.exposure_gain,
                       noise, {"setup": 1e3 * (t_setup - t0), "read": 1e3 * (t_read - t_setup),
                               "compose": 1e3 * (t_compose - t_read)})
    if comp.srgb is not None:
        meta["srgb_exposure"] = comp.srgb_exposure  # what the sRGB rendering applied on top of raw
    return arrays, meta


def build_sample(spec: SampleSpec, ctx: Context) -> tuple[dict[str, np.ndarray], dict]:
    """:func:`plan` then :func:`build`, without admission (for in-process use and benchmarks)."""
    return build(plan(spec, ctx), ctx)
