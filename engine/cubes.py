"""A plan's decoded cubes through the composition context's LRU cache, and the cache's keys (public, so
``serve --warm`` fills the same entries)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from illumix.engine.context import Context
    from illumix.engine.plan import Plan


def cube_bytes(p: Plan) -> int:
    """Decoded bytes of one whole float32 cube of the plan's view."""
    return p.full[0] * p.full[1] * p.metas[0].n_bands * 4


def cube_key(scene: str, view: str, group: str, kind: str, denoise: str, stamp: str) -> tuple:
    """The cube cache's key of a decoded whole cube (public so ``serve --warm`` fills the same entries).
    ``stamp`` names the stored version (the node's write id, :attr:`engine.plan.Plan.stamps`): a cube
    replaced while the service runs — by any machine — is a new entry, never served from the old one,
    and the transport and illumination cubes of one sample always come from the same write."""
    return (scene, view, group, kind, denoise, stamp)


def aov_key(scene: str, view: str, name: str, stamp: tuple) -> tuple:
    """The cube cache's key of a view's whole AOV; ``stamp``: the render stamps of all its groups' cubes."""
    return (scene, view, "aov", name, stamp)


def plan_cube_key(p: Plan, group: str, kind: str) -> tuple:
    """The cube cache's key of a group's ``kind`` cube in plan ``p`` (:func:`cube_key`)."""
    return cube_key(p.scene, p.view, group, kind, p.denoise, p.stamps[p.groups.index(group)])


def projection_key(p: Plan, group: str, kind: str, skey, ikey) -> tuple:
    """The key of a group's whole-frame projection (:mod:`engine.projections`) for a sensor and an
    illuminant key (:class:`engine.library.Library`)."""
    return (plan_cube_key(p, group, kind), skey, ikey)


def frame_bytes(p: Plan) -> int:
    """Bytes of one whole-frame float32 camera-raw projection of the plan's view."""
    return p.full[0] * p.full[1] * 3 * 4


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
