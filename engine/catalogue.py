"""What a composition context can serve, as plain data: the store's scenes, views and light groups,
and the sensors and illuminants (built-in, parametric, uploaded). ``GET /scenes``, ``/sensors`` and
``/illuminants`` answer these (wrapped in their response models); the client's local mode returns
them as they are."""

from __future__ import annotations

from functools import lru_cache

from illumix.engine.context import Context
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID, SpectralGrid
from illumix.store import StoreError


def scenes(ctx: Context) -> list[dict]:
    """Every scene, view and light group the store holds: ``[{"name", "views": [{"name", "width",
    "height", "groups": [{"name", "emission", "illumination", "denoised"}], "damaged"}]}]``. A view
    whose metadata or a group's is damaged is listed with ``damaged`` saying why (and no size or
    groups): never silently left out, and never hiding the healthy views beside it."""
    store = ctx.store
    out = []
    for s in store.scenes():
        views = []
        try:
            names, broken = store.view_health(s)
        except StoreError as exc:  # the scene's own group document
            out.append({"name": s, "views": [], "damaged": str(exc)})
            continue
        for v in sorted([*names, *broken]):
            try:
                views.append(_view(store, s, v) if v in names else _damaged(v, broken[v]))
            except StoreError as exc:
                views.append(_damaged(v, str(exc)))
        out.append({"name": s, "views": views, "damaged": None})
    return out


def _view(store, s: str, v: str) -> dict:
    vm = store.view_meta(s, v)
    groups = [{"name": g, "emission": m.emission_name,
               "illumination": m.illumination is not None and m.illumination.storage is not None,
               "denoised": m.denoised.method if m.denoised is not None and m.denoised.storage else None}
              for g, m in ((g, store.cube_meta(s, v, g)) for g in store.groups(s, v))]
    return {"name": v, "width": vm.width, "height": vm.height, "groups": groups, "damaged": None}


def _damaged(v: str, why: str) -> dict:
    return {"name": v, "width": None, "height": None, "groups": [], "damaged": why}


def sensors(ctx: Context) -> dict:
    """``{"builtin": usable on the default grid, "unavailable": {name: why}, "uploaded": [...]}``."""
    usable, unusable = sen.availability(DEFAULT_GRID)
    return {"builtin": usable, "unavailable": unusable, "uploaded": ctx.library.uploaded_sensors()}


def illuminants(ctx: Context) -> dict:
    """``{"builtin": usable on the default grid, "unavailable": {name: why}, "parametric": {kind:
    {"min_kelvin", "max_kelvin"}}, "uploaded"}`` (parametric names read ``<kind>:<kelvin>``, e.g.
    ``blackbody:3200``). As for sensors: a tabulated illuminant whose data stop short of the grid (the
    ISO 7589 tables end at 690 nm) is listed under ``unavailable`` with the reason, not as usable."""
    usable, unusable = illuminant_availability(DEFAULT_GRID)
    return {"builtin": list(usable), "unavailable": dict(unusable),
            "parametric": {k: {"min_kelvin": lo, "max_kelvin": hi} for k, (lo, hi) in ill.PARAMETRIC.items()},
            "uploaded": ctx.library.uploaded_illuminants()}


@lru_cache(maxsize=8)
def illuminant_availability(grid: SpectralGrid) -> tuple[tuple[str, ...], tuple[tuple[str, str], ...]]:
    """``(usable names, ((unusable name, why), …))`` of the built-in illuminants on ``grid``
    (remembered: the tables are fixed for the process)."""
    usable, unusable = [], []
    for name in ill.builtin_names():
        try:
            ill.illuminant_spd(name, grid)
            usable.append(name)
        except SpectralError as exc:
            unusable.append((name, str(exc)))
    return tuple(usable), tuple(unusable)


__all__ = ["illuminant_availability", "illuminants", "scenes", "sensors"]
