"""Camera views chosen for mixed light.

Candidates stand on free floor (at least :data:`CLEARANCE` from walls and furniture), at human
height (1.45–1.75 m) or tabletop height (0.9–1.2 m, looking down at a top with things on it), aimed
at points of interest (furniture, tops, lamps) at least 1.2 m away, horizontal field of view 55–80°.

:func:`mixed_fraction` is the cheap probe that measures what a view is worth: each light group
rendered alone with Mitsuba's own spectral path tracer at low resolution and spp (the group's own
emission, every emitter strength as in the scene), luminance ``Y`` per pixel, lightly blurred
(3×3) to keep the probe's noise out of the shares, then the strongest group's share
``max_g Y_g / Σ_g Y_g``. The mixed fraction is the share of lit pixels (``Σ Y > 0``) where it is
below :data:`MIXED_SHARE` — where no single illuminant explains the white point, the pixels
white-balance methods get wrong. One Mitsuba scene per group renders every candidate view at once
(a ``batch`` sensor: one kernel per group).
"""

from __future__ import annotations

import numpy as np

CLEARANCE = 0.35
MIXED_SHARE = 0.8
TARGET_SEEN, NEAR, NEAR_SHARE = 0.8, 1.0, 0.3  # clear_views: what makes a view show something
PROBE_RES = (48, 36)
PROBE_SPP = 16


def candidates(rng: np.random.Generator, placer, n: int, interest: list[tuple[float, float, float]],
               resolution=(240, 180)) -> list[dict]:
    """``n`` candidate view documents (see module docstring)."""
    dist = placer.clearance_map()
    ii, jj = np.nonzero(dist >= CLEARANCE)
    if ii.size == 0:
        ii, jj = np.nonzero(dist >= dist.max() * 0.9)
    tops = [(s.center[0], s.y, s.center[1]) for s in placer.surfaces if s.taken]
    views: list[dict] = []
    for _ in range(n * 6):
        if len(views) == n:
            break
        k = int(rng.integers(ii.size))
        x, z = placer.cell_center(int(ii[k]), int(jj[k]))
        x, z = x + rng.uniform(-0.02, 0.02), z + rng.uniform(-0.02, 0.02)
        low = tops and rng.random() < 0.35
        pool = tops if low else interest
        tx, ty, tz = pool[int(rng.integers(len(pool)))]
        d = float(np.hypot(tx - x, tz - z))
        if d < 1.2 or d > 9:
            continue
        y = float(rng.uniform(0.9, 1.2) if low else rng.uniform(1.45, 1.75))
        ty = float(ty if low else np.clip(ty + rng.uniform(-0.2, 0.3), 0.4, 1.6))
        views.append({"name": f"view{len(views)}", "origin": [round(x, 4), round(y, 4), round(z, 4)],
                      "target": [round(float(tx), 4), round(ty, 4), round(float(tz), 4)], "up": [0, 1, 0],
                      "fov": round(float(rng.uniform(55, 80)), 2), "resolution": list(resolution)})
    return views


def clear_views(scene, views: list[str], resolution=PROBE_RES) -> np.ndarray:
    """``(n_views,)`` bool: the view sees its target (the centre pixel's depth is at least
    :data:`TARGET_SEEN` of the distance to it) and is not filled by a close surface (at most
    :data:`NEAR_SHARE` of the pixels nearer than :data:`NEAR` m) — a view at a wall a door away from
    its target is lit by every group (mixed) and shows nothing."""
    from illumix.renderer_jobs.mitsuba.view_probe import view_depth

    depth = view_depth(scene, views, resolution)
    h, w = depth.shape[1:]
    dist = np.array([np.linalg.norm(np.subtract(scene.view(v).target, scene.view(v).origin)) for v in views])
    centre = depth[:, h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1].max(axis=(1, 2))
    near = ((depth > 0) & (depth < NEAR)).mean(axis=(1, 2))
    return (centre >= TARGET_SEEN * dist) & (near <= NEAR_SHARE)


def probe(scene, views: list[str] | None = None, resolution=PROBE_RES,
          spp: int = PROBE_SPP) -> tuple[np.ndarray, np.ndarray]:
    """``(mixed fraction (V,), each group's share of the view's luminance (V, G))`` (module docstring)."""
    import cv2

    from illumix.renderer_jobs.mitsuba.view_probe import group_luminance

    views = [v.name for v in scene.views] if views is None else views
    groups = scene.group_names
    y = np.stack([group_luminance(scene, views, g, resolution, spp) for g in groups])  # (G, V, H, W)
    y = np.stack([[cv2.blur(y[g, v].astype(np.float32), (3, 3)) for v in range(y.shape[1])] for g in range(y.shape[0])])
    total = y.sum(axis=0)
    lit = total > 0
    share = np.where(lit, y.max(axis=0) / np.where(lit, total, 1), 1.0)
    mixed = (share < MIXED_SHARE) & lit
    frac = mixed.sum(axis=(1, 2)) / np.maximum(lit.sum(axis=(1, 2)), 1)
    per_group = y.sum(axis=(2, 3)).T
    return frac, per_group / np.maximum(per_group.sum(axis=1, keepdims=True), 1e-30)


def mixed_fractions(scene, views: list[str] | None = None, resolution=PROBE_RES, spp: int = PROBE_SPP) -> np.ndarray:
    """The mixed-light fraction of each view (see module docstring); 0 for a single-group scene."""
    return probe(scene, views, resolution, spp)[0]


def mixed_fraction(scene, view: str, resolution=PROBE_RES, spp: int = PROBE_SPP) -> float:
    return float(mixed_fractions(scene, [view], resolution, spp)[0])
