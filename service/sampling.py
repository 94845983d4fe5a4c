"""Compose one sample from the store: resolve the request, read (cached) cubes, run the physics.

``build_sample(spec, ctx)`` → ``(arrays, meta)``: arrays named as in :data:`retarget.compose.OUTPUTS`,
meta a JSON-able dict (scene/view/groups, illuminants with their sensor white points, intensities,
CCMs, exposure gain, seeds, store and renderer provenance, timings).
"""

from __future__ import annotations

import random
import time
from dataclasses import dataclass

import cv2
import numpy as np

from retarget.compose import compose
from retarget.errors import SpectralError, unknown_name
from retarget.sensor_model import mosaic, simulate_raw
from service.cache import ArrayCache
from service.library import Library
from service.limits import Limits
from service.spec import SampleSpec


class NotFound(SpectralError):
    """A scene or view that is not in the store (HTTP 404)."""


@dataclass
class Context:
    store: object
    library: Library
    cache: ArrayCache
    limits: Limits


def _pick(kind: str, name: str | None, options: list[str], rng: random.Random) -> str:
    if not options:
        raise NotFound(f"the store has no {kind}s; render some with `illumix render`")
    if name is None:
        return rng.choice(sorted(options))
    if name not in options:
        err = unknown_name(kind, name, options)
        raise NotFound(str(err))
    return name


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
    if any(not (np.isfinite(a) and 0 <= a <= 1e9) for a in intens):
        raise SpectralError("intensities must be finite numbers between 0 and 1e9")
    return names, [float(a) for a in intens]


def _window(spec: SampleSpec, width: int, height: int, limits: Limits) -> tuple[tuple[int, int, int, int], tuple[int, int]]:
    x, y, w, h = spec.crop if spec.crop else (0, 0, width, height)
    if x + w > width or y + h > height:
        raise SpectralError(f"crop {x},{y},{w},{h} exceeds the view's {width}x{height} frame")
    out_w, out_h = spec.size if spec.size else (w, h)
    if max(out_w, out_h) > limits.max_side or out_w * out_h > limits.max_pixels:
        raise SpectralError(f"output {out_w}x{out_h} exceeds the limits (side <= {limits.max_side}, "
                            f"pixels <= {limits.max_pixels}); crop or resize smaller")
    return (x, y, w, h), (out_w, out_h)


def _resizer(out_w: int, out_h: int, w: int, h: int):
    if (out_w, out_h) == (w, h):
        return None
    interp = cv2.INTER_AREA if out_w <= w and out_h <= h else cv2.INTER_LINEAR

    def resize(group_raw: np.ndarray) -> np.ndarray:
        return np.stack([cv2.resize(g, (out_w, out_h), interpolation=interp) for g in group_raw])

    return resize


def read_cube(ctx: Context, scene: str, view: str, group: str, window: tuple[int, int, int, int],
              full: tuple[int, int]) -> np.ndarray:
    """A crop of a cube through the LRU cache (a cached full frame serves any crop)."""
    x, y, w, h = window
    full_key = (scene, view, group, None)
    cached = ctx.cache.peek(full_key)
    if cached is not None:
        return cached[y:y + h, x:x + w]
    if (w, h) == full:
        return ctx.cache.get(full_key, lambda: ctx.store.read_cube(scene, view, group))
    return ctx.cache.get((scene, view, group, window),
                         lambda: ctx.store.read_cube(scene, view, group, crop=window))


def build_sample(spec: SampleSpec, ctx: Context) -> tuple[dict[str, np.ndarray], dict]:
    t0 = time.perf_counter()
    seed = spec.seed if spec.seed is not None else random.SystemRandom().randrange(2**31)
    rng = random.Random(seed)
    store = ctx.store
    scene = _pick("scene", spec.scene, store.scenes(), rng)
    view = _pick("view", spec.view, store.views(scene), rng)
    groups = store.groups(scene, view)
    if not groups:
        raise NotFound(f"view {scene}/{view} has no complete light groups yet; finish rendering it")
    metas = [store.cube_meta(scene, view, g) for g in groups]
    names, intensities = _lighting(spec, groups, [m.emission_name for m in metas])
    if len([n for n in names if n]) > ctx.limits.max_groups:
        raise SpectralError(f"at most {ctx.limits.max_groups} illuminants per request")
    vmeta = store.view_meta(scene, view)
    window, (out_w, out_h) = _window(spec, vmeta.width, vmeta.height, ctx.limits)
    grid = metas[0].spectral_grid
    if any(m.spectral_grid != grid for m in metas):
        raise SpectralError(f"view {scene}/{view}: light groups are on different spectral grids; re-render")
    sensor, skey = ctx.library.sensor(spec.sensor, grid)
    spds, ikeys = [], []
    for n in names:
        spd, key = ctx.library.illuminant(n or "E", grid)
        spds.append(spd)
        ikeys.append(key)
    spds_arr = np.stack(spds)
    ccms, fit_de = zip(*(ctx.library.ccm(sensor, skey, s, k) for s, k in zip(spds, ikeys)))
    t_setup = time.perf_counter()
    x, y, w, h = window
    zero = np.broadcast_to(np.float32(0), (h, w, grid.n_bands))
    cubes = []
    for g, m, a in zip(groups, metas, intensities):
        skip = a == 0 or m.empty
        cubes.append(zero if skip else read_cube(ctx, scene, view, g, window, (vmeta.width, vmeta.height)))
    emissions = np.stack([np.asarray(m.emission, dtype=np.float64) for m in metas])
    t_read = time.perf_counter()
    want = set(spec.array_outputs())
    comp = compose(cubes, emissions=emissions, illuminants=spds_arr, intensities=np.array(intensities),
                   sensor=sensor, ccms=np.stack(ccms), outputs=want | ({"raw"} if spec.noise else set()),
                   exposure=spec.exposure_value(), group_names=groups,
                   resize=_resizer(out_w, out_h, w, h))
    arrays = comp.outputs()
    noise = spec.noise_model()
    if noise is not None and "raw" in want:
        arrays["raw"] = simulate_raw(arrays["raw"], noise, seed=seed)
    if spec.bayer and "raw" in want:
        arrays["raw"] = mosaic(arrays["raw"], spec.bayer)
    arrays = {k: v for k, v in arrays.items() if k in want}
    t_compose = time.perf_counter()
    meta = {
        "scene": scene, "view": view, "groups": groups, "seed": seed,
        "sensor": {"name": sensor.name, "source": sensor.source},
        "illuminants": [
            {"group": g, "illuminant": n, "intensity": a,
             "white_point_rgb": [float(v) for v in wp],
             "ccm": np.asarray(c).round(8).tolist(), "ccm_fit_delta_e00_mean": float(de)}
            for g, n, a, wp, c, de in zip(groups, names, intensities, comp.white_points, ccms, fit_de)
        ],
        "crop": list(window), "size": [out_w, out_h], "exposure_gain": comp.exposure_gain,
        "noise": None if noise is None else noise.__dict__ | {"seed": seed}, "bayer": spec.bayer,
        "grid": grid.to_dict(),
        "provenance": [{"group": g, "emission": m.emission_name, "renderer": m.renderer.model_dump(),
                        "spp": m.spp, "seed": m.seed, "scene_hash": m.scene_hash, "created": m.created,
                        "empty": m.empty} for g, m in zip(groups, metas)],
        "timings_ms": {"setup": 1e3 * (t_setup - t0), "read": 1e3 * (t_read - t_setup),
                       "compose": 1e3 * (t_compose - t_read)},
    }
    return arrays, meta
