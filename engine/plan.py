"""Resolve a sample request from the store's metadata alone (no cube is read): names, lighting,
window, ground truth and denoising — so a request is refused before it costs anything."""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from illumix.engine.errors import NotFound, TooLarge
from illumix.engine.lighting import RULES, group_kinds, illuminant_kind, pair_lighting
from illumix.engine.limits import Limits
from illumix.engine.spec import CAMERA_NOISE, SPECTRAL_OUTPUTS, SampleSpec
from illumix.retarget.compose import GT_OUTPUTS
from illumix.retarget.errors import SpectralError, unknown_name

if TYPE_CHECKING:
    from illumix.engine.context import Context


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
    sensor: str = ""  # the sensor to project through: sensor=random becomes random:<seed> (a drawn camera)
    noise: object = None  # the NoiseModel of noise= (noise=camera: the sensor's own), or None
    bayer: str | None = None  # the raw's mosaic (bayer=, else the camera's own with noise=camera; DNG: RGGB)
    stamps: list[str] = field(default_factory=list)  # each group's cube version (its write id): cache keys
    lighting: dict = field(default_factory=dict)  # the rule that lit the groups and each group's kind (meta)

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


def _lighting(spec: SampleSpec, groups: list[str], metas: list, classify: Callable[[str], str | None]
              ) -> tuple[list[str | None], list[float], dict]:
    """Illuminant name per group (``None`` = off), intensities and the rule used (:mod:`engine.lighting`:
    ``pair=`` by the groups' kinds where known, else in order; ``illuminants=`` as given). Without
    pair=/illuminants=, each group is lit as it was rendered: D65 for flat-emission cubes, else the
    cube's own emission."""
    if spec.pair is not None and spec.illuminants is not None:
        raise SpectralError("give either pair= or illuminants=, not both")
    kinds = group_kinds(groups, metas, classify)
    which: list[int | None] | None = None
    if spec.pair is not None:
        if len(spec.pair) != 2:
            raise SpectralError(f"pair needs exactly two illuminants, e.g. pair=A,D65; got {spec.pair}")
        if len(groups) < 2:
            raise SpectralError(f"pair= needs a view with two light groups; this view has {groups}; "
                                "use illuminants= with one entry")
        names, which, rule, why = pair_lighting(list(spec.pair), [k for k, _ in kinds], classify)
    elif spec.illuminants is not None:
        if len(spec.illuminants) != len(groups):
            raise SpectralError(f"illuminants= needs one entry per light group {groups} "
                                f"({len(groups)}), got {len(spec.illuminants)}")
        names, rule, why = list(spec.illuminants), "explicit", RULES["explicit"]
    else:
        names = ["D65" if m.emission_name == "flat" else m.emission_name for m in metas]
        rule, why = "rendered", RULES["rendered"]
    intens = _intensities(spec.intensities, names, which)
    info = {"rule": rule, "why": why,
            "groups": [{"group": g, "kind": k, "kind_from": src, "illuminant": n}
                       for g, (k, src), n in zip(groups, kinds, names)]}
    return names, intens, info


def _intensities(given: list[float] | None, names: list[str | None], which: list[int | None] | None) -> list[float]:
    """Per group: 1 for lit groups by default; else one value per group, per lit group or (with
    ``pair=``, ``which``: each group's index in the pair) one per illuminant of the pair."""
    if given is None:
        return [1.0 if n is not None else 0.0 for n in names]
    intens = list(given)
    lit = [i for i, n in enumerate(names) if n is not None]
    if which is not None and len(intens) == 2:  # one per illuminant of the pair, in the pair's order
        intens = [0.0 if w is None else intens[w] for w in which]
    elif len(intens) == len(lit) and len(intens) != len(names):
        full = [0.0] * len(names)
        for i, v in zip(lit, intens):
            full[i] = v
        intens = full
    if len(intens) != len(names):
        also = ", or one per illuminant of the pair (2)" if which is not None else ""
        raise SpectralError(f"intensities= needs one value per lit group ({len(lit)}){also}, got {len(intens)}")
    return [float(a) for a in intens]


def _window(spec: SampleSpec, width: int, height: int, limits: Limits) -> tuple[tuple[int, int, int, int], tuple[int, int]]:
    x, y, w, h = spec.crop if spec.crop else (0, 0, width, height)
    if x + w > width or y + h > height:
        raise SpectralError(f"crop {x},{y},{w},{h} exceeds the view's {width}x{height} frame")
    out_w, out_h = spec.size if spec.size else (w, h)
    if max(out_w, out_h) > limits.max_side or out_w * out_h > limits.max_pixels:
        raise TooLarge(f"output {out_w}x{out_h} exceeds the limits (side <= {limits.max_side}, "
                       f"pixels <= {limits.max_pixels}); crop or resize smaller")
    return (x, y, w, h), (out_w, out_h)


def plan(spec: SampleSpec, ctx: Context) -> Plan:
    """Resolve a request from metadata (no cube read). Raises :class:`engine.errors.NotFound`,
    :class:`engine.errors.TooLarge` or :class:`retarget.errors.SpectralError`."""
    seed = spec.seed if spec.seed is not None else random.SystemRandom().randrange(2**31)
    rng = random.Random(seed)
    store = ctx.store
    scene = _pick("scene", spec.scene, store.scenes, store.has_scene, rng)
    view = _pick("view", spec.view, lambda: store.views(scene), lambda v: store.has_view(scene, v), rng)
    groups = store.groups(scene, view)
    if not groups:
        raise NotFound(f"view {scene}/{view} has no complete light groups yet; finish rendering it")
    nodes = [store.complete_node(scene, view, g) for g in groups]
    metas = [meta for _, _, meta in nodes]
    names, intensities, lighting = _lighting(spec, groups, metas, _classifier(ctx, metas[0].spectral_grid))
    if len([n for n in names if n]) > ctx.limits.max_groups:
        raise SpectralError(f"at most {ctx.limits.max_groups} illuminants per request")
    vmeta = store.view_meta(scene, view)
    window, out_size = _window(spec, vmeta.width, vmeta.height, ctx.limits)
    if any(m.spectral_grid != metas[0].spectral_grid for m in metas):
        raise SpectralError(f"view {scene}/{view}: light groups are on different spectral grids; re-render")
    p = Plan(spec, seed, scene, view, groups, metas, names, intensities, window, (vmeta.width, vmeta.height), out_size,
             aovs=list(vmeta.aovs), stamps=[state["write_id"] for _, state, _ in nodes], lighting=lighting)
    p.sensor = f"random:{seed & 0xFFFFFFFF}" if spec.sensor.lower() == "random" else spec.sensor
    camera = spec.noise is not None and spec.noise.strip().lower() == CAMERA_NOISE
    p.noise, cfa = ctx.library.camera_noise(p.sensor) if camera else (spec.noise_model(), None)
    p.bayer = _mosaic(spec, cfa)
    p.gt, p.gt_why = _ground_truth(spec, p)
    p.denoise, p.denoise_why = _denoising(spec, p)
    wanted = set(spec.outputs)
    p.illumination = bool(SPECTRAL_OUTPUTS & wanted) or (p.gt == "physical" and bool(PHYSICAL_OUTPUTS & wanted))
    return p


def _classifier(ctx: Context, grid) -> Callable[[str], str | None]:
    """:func:`engine.lighting.illuminant_kind` of a name, through the context's library (uploads too)."""
    seen: dict[str, str | None] = {}

    def classify(name: str) -> str | None:
        if name not in seen:
            seen[name] = illuminant_kind(name, lambda x: ctx.library.illuminant(x, grid)[0], grid)
        return seen[name]
    return classify


def _mosaic(spec: SampleSpec, camera_cfa: str | None) -> str | None:
    """The raw's Bayer pattern: ``bayer=`` as given (``bayer=none``: none); else the camera's own
    (``noise=camera``, from its DNG); else RGGB for a DNG, none otherwise."""
    if "bayer" in spec.model_fields_set:
        return spec.bayer
    if camera_cfa:
        return camera_cfa
    return "RGGB" if spec.format == "dng" else None


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
