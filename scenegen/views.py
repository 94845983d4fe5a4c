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

A kept view must be mixed enough to be worth its cubes (:class:`MixedLightRule`, :func:`probe_views`):
by default at least 30 % of its valid pixels (some light arrives) have **two** groups each bringing
more than 20 % of the pixel's light. A room with a "screen" group giving 4 % of the light has views
that are single-illuminant in all but name; they are dropped, and the reason is given per view.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

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


class MixedLightRule(BaseModel):
    """The least mixed light a kept view must have (module docstring): at least ``min_fraction`` of its
    valid pixels with two light groups each above ``min_share`` of the pixel's light."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    min_fraction: float = Field(default=0.3, ge=0.0, le=1.0,
                                description="share of the view's valid pixels that must be mixed (0: keep every view)")
    min_share: float = Field(default=0.2, gt=0.0, le=0.5,
                             description="a group counts in a pixel above this share of the pixel's light")


@dataclass
class ViewProbe:
    """What :func:`probe_views` measured per view: ``mixed`` the mixed-light fraction (module
    docstring), ``shares`` ``(V, G)`` each group's share of the view's light, ``two_group`` the
    fraction of valid pixels with two groups above the rule's share, ``keep`` whether the view passes
    the rule, ``why`` a line per dropped view."""

    views: list[str]
    mixed: np.ndarray
    shares: np.ndarray
    two_group: np.ndarray
    keep: np.ndarray
    why: list[str] = field(default_factory=list)


def two_group_fraction(y: np.ndarray, min_share: float) -> np.ndarray:
    """``(V,)``: of each view's valid pixels (any light, ``Σ_g Y > 0``), the fraction whose second
    strongest group brings more than ``min_share`` of the pixel's light. ``y``: ``(G, V, H, W)``
    luminance per group (non-negative); 0 for a view without valid pixels or with one group."""
    y = np.asarray(y, np.float64)
    total = y.sum(axis=0)
    valid = total > 0
    if y.shape[0] < 2:
        return np.zeros(y.shape[1])
    second = np.sort(y, axis=0)[-2]  # (V, H, W): the second-largest group per pixel
    mixed = valid & (second > min_share * np.where(valid, total, 1.0))
    return mixed.sum(axis=(1, 2)) / np.maximum(valid.sum(axis=(1, 2)), 1)


def apply_rule(views: list[str], two_group: np.ndarray, rule: MixedLightRule) -> tuple[np.ndarray, list[str]]:
    """``(keep (V,) bool, a line per dropped view)`` of :class:`MixedLightRule`."""
    keep = np.asarray(two_group) >= rule.min_fraction
    why = [f"view {v}: {f:.0%} of its pixels have two light groups above {rule.min_share:.0%} of the light "
           f"(at least {rule.min_fraction:.0%} needed); dropped" for v, f, k in zip(views, two_group, keep) if not k]
    return keep, why


def _luminance(scene, views: list[str], resolution, spp: int) -> np.ndarray:
    """``(G, V, H, W)`` each group's probe luminance, blurred 3×3 (module docstring)."""
    import cv2

    from illumix.renderer_jobs.mitsuba.view_probe import group_luminance

    y = np.stack([group_luminance(scene, views, g, resolution, spp) for g in scene.group_names])
    return np.stack([[cv2.blur(y[g, v].astype(np.float32), (3, 3)) for v in range(y.shape[1])]
                     for g in range(y.shape[0])])


def probe_views(scene, views: list[str] | None = None, rule: MixedLightRule | None = None,
                resolution=PROBE_RES, spp: int = PROBE_SPP) -> ViewProbe:
    """One probe of ``views`` (all the scene's by default) and the verdict of ``rule`` (:class:`ViewProbe`;
    default :class:`MixedLightRule`)."""
    rule = MixedLightRule() if rule is None else rule
    views = [v.name for v in scene.views] if views is None else views
    y = _luminance(scene, views, resolution, spp)
    frac, shares = _fractions(y)
    two = two_group_fraction(y, rule.min_share)
    keep, why = apply_rule(views, two, rule)
    return ViewProbe(views, frac, shares, two, keep, why)


def probe(scene, views: list[str] | None = None, resolution=PROBE_RES,
          spp: int = PROBE_SPP) -> tuple[np.ndarray, np.ndarray]:
    """``(mixed fraction (V,), each group's share of the view's luminance (V, G))`` (module docstring)."""
    views = [v.name for v in scene.views] if views is None else views
    return _fractions(_luminance(scene, views, resolution, spp))


def _fractions(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(mixed fraction (V,), shares (V, G))`` of ``(G, V, H, W)`` probe luminance."""
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
