"""What every renderer backend returns for one cube, and which emitters a cube of some groups needs
(:mod:`renderer_jobs.backends`): renderer-independent, so the Cycles backend imports nothing of the
Mitsuba one for them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from illumix.scene.model import Scene

# Broad bands (nm) whose mean reflectance forms the RGB albedo AOV (every backend's).
ALBEDO_BANDS = ((600.0, 700.0), (500.0, 600.0), (400.0, 500.0))

@dataclass
class CubeResult:
    """A rendered cube ``(H, W, n_bands)`` float32 of band averages, with what it was rendered with
    (and its illumination cube, same shape and units)."""

    cube: np.ndarray
    emission: np.ndarray
    emission_name: str
    renderer: dict
    stats: dict = field(default_factory=dict)
    illumination: np.ndarray | None = None  # (H, W, n_bands) float32, when RenderSettings.illumination
    #: (H, W, 2) float32: the cube's band sum and its variance from the band sets' spread, or None
    #: (renderer_jobs.mitsuba.band_render.set_noise; the denoiser weighs its bias against it)
    noise: np.ndarray | None = None


def group_list(scene: Scene, group: str | list[str] | None) -> list[str]:
    """``group`` as a list of checked group names (``None``: every group of the scene)."""
    groups = [group] if isinstance(group, str) else (scene.group_names if group is None else list(group))
    for g in groups:
        scene.group(g)
    return groups


def emitter_passes(scene: Scene, groups: list[str]) -> list[str]:
    """The passes a cube of ``groups`` needs: ``"without"`` (every emitter but portals) when the groups
    have non-portal emitters, ``"only"`` (portals alone) when they have portals. Portals render in a
    pass of their own (they occlude nothing); the cube is the passes' sum."""
    emitters = [e for g in groups for e in scene.emitters_of(g)]
    return [p for p, present in (("without", any(not scene.is_portal(e) for e in emitters)),
                                 ("only", any(scene.is_portal(e) for e in emitters))) if present]
