"""What a composition context can serve, as plain data: the store's scenes, views and light groups,
and the sensors and illuminants (built-in, parametric, uploaded). ``GET /scenes``, ``/sensors`` and
``/illuminants`` answer these (wrapped in their response models); the client's local mode returns
them as they are."""

from __future__ import annotations

from illumix.engine.context import Context
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.retarget.grid import DEFAULT_GRID


def scenes(ctx: Context) -> list[dict]:
    """Every scene, view and light group the store holds: ``[{"name", "views": [{"name", "width",
    "height", "groups": [{"name", "emission", "illumination", "denoised"}]}]}]``. A damaged view
    raises the store's error (never silently left out)."""
    store = ctx.store
    out = []
    for s in store.scenes():
        views = []
        for v in store.views(s):
            vm = store.view_meta(s, v)
            groups = [{"name": g, "emission": m.emission_name,
                       "illumination": m.illumination is not None and m.illumination.storage is not None,
                       "denoised": m.denoised.method if m.denoised is not None and m.denoised.storage else None}
                      for g, m in ((g, store.cube_meta(s, v, g)) for g in store.groups(s, v))]
            views.append({"name": v, "width": vm.width, "height": vm.height, "groups": groups})
        out.append({"name": s, "views": views})
    return out


def sensors(ctx: Context) -> dict:
    """``{"builtin": usable on the default grid, "unavailable": {name: why}, "uploaded": [...]}``."""
    usable, unusable = sen.availability(DEFAULT_GRID)
    return {"builtin": usable, "unavailable": unusable, "uploaded": ctx.library.uploaded_sensors()}


def illuminants(ctx: Context) -> dict:
    """``{"builtin", "parametric": {kind: {"min_kelvin", "max_kelvin"}}, "uploaded"}``
    (parametric names read ``<kind>:<kelvin>``, e.g. ``blackbody:3200``)."""
    return {"builtin": ill.builtin_names(),
            "parametric": {k: {"min_kelvin": lo, "max_kelvin": hi} for k, (lo, hi) in ill.PARAMETRIC.items()},
            "uploaded": ctx.library.uploaded_illuminants()}


__all__ = ["illuminants", "scenes", "sensors"]
