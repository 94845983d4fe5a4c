"""Skip what a scene doesn't need, per pixel: which pixels of a view can see any geometry at all?

For a light group without a sky (``constant``/``envmap``), a camera ray that leaves the scene
carries exactly zero radiance (point, spot and directional lights are not visible; area lights are
shapes). Such pixels need no paths. :func:`covered_pixels` finds them conservatively: every shape
(portals included) is replaced by points whose convex hull contains it
(:func:`renderer_jobs.mitsuba.scene_dict.shape_hull_points`), the points are projected through the
view's pinhole camera, and each shape covers the pixel rectangle around its projection, widened
by one pixel. A pixel outside every rectangle cannot be reached by any ray through its footprint.
If any hull point lies at or behind the camera plane the projection is unbounded and every pixel
counts as covered (rooms seen from inside: nothing is skipped there).

Measured (``bench/render.py --parts background``): in an open scene where ~2/3 of the pixels see
nothing, tracing them was about half of the render's CPU time; in the (closed) demo room, 0.
"""

from __future__ import annotations

import numpy as np

from illumix.renderer_jobs.mitsuba.scene_dict import shape_hull_points
from illumix.scene.model import Scene
from illumix.scene.schema import ConstantSky, EnvMapSky

NEAR = 1e-6  # metres: hull points nearer than this to the camera plane make the projection unbounded


def camera_frame(scene: Scene, view: str) -> tuple[np.ndarray, np.ndarray]:
    """``(origin (3,), rows (3, 3))``: the camera's position and its right-handed frame as Mitsuba's
    ``look_at`` builds it — rows ``left``, ``up``, ``forward`` (unit vectors)."""
    v = scene.view(view)
    o = np.asarray(v.origin, dtype=np.float64)
    f = np.asarray(v.target, dtype=np.float64) - o
    f /= np.linalg.norm(f)
    left = np.cross(np.asarray(v.up, dtype=np.float64), f)
    left /= np.linalg.norm(left)
    return o, np.stack([left, np.cross(f, left), f])


def project(scene: Scene, view: str, points: np.ndarray, resolution: tuple[int, int] | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """Film coordinates ``(n, 2)`` in pixels (x right, y down, origin at the top-left corner) and
    camera depths ``(n,)`` in metres of world points ``(n, 3)``; horizontal field of view."""
    v = scene.view(view)
    w, h = resolution or v.resolution
    o, rows = camera_frame(scene, view)
    c = (np.asarray(points, dtype=np.float64) - o) @ rows.T
    z = c[:, 2]
    scale = (w / 2) / np.tan(np.radians(v.fov) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = np.stack([w / 2 - scale * c[:, 0] / z, h / 2 - scale * c[:, 1] / z], axis=1)
    return xy, z


def group_sees_sky(scene: Scene, groups: list[str]) -> bool:
    """True when a ray leaving the scene can carry light of ``groups`` (they include a sky)."""
    return any(isinstance(e, (ConstantSky, EnvMapSky)) for g in groups for e in scene.emitters_of(g))


def covered_pixels(scene: Scene, view: str, resolution: tuple[int, int] | None = None) -> np.ndarray | None:
    """``(H, W)`` bool: pixels some camera ray of which may hit geometry (module docstring), or None
    when that may be every pixel."""
    v = scene.view(view)
    w, h = resolution or v.resolution
    cov = np.zeros((h, w), dtype=bool)
    for sh in scene.shapes:
        xy, z = project(scene, view, shape_hull_points(scene, sh), (w, h))
        if np.any(z <= NEAR) or not np.all(np.isfinite(xy)):
            return None
        x0, y0 = np.floor(xy.min(axis=0)).astype(int) - 1
        x1, y1 = np.ceil(xy.max(axis=0)).astype(int) + 1
        cov[max(y0, 0):max(min(y1, h), 0), max(x0, 0):max(min(x1, w), 0)] = True
    return cov
