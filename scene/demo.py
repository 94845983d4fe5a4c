"""Procedural scenes: the seeded demo room and the closed-form validation chart.

``demo_room(seed)`` — a closed room (floor, four walls, ceiling) with a window opening in the left
wall. Light groups:

- ``daylight``: a directional sun through the window plus the sky seen through it (a uniform sky,
  as a *portal* emitter filling the window opening: exact for a constant sky and much less noisy
  than a ``constant`` environment that must be found through the window by chance);
- ``ceiling``: a rectangular area light under the ceiling;
- ``desk``: a spot light on the table aimed at the wall chart.

Objects: a table (cube), a rough-plastic ball, a rough-conductor (aluminium) can, a small glass
sphere, and a 24-patch ColorChecker Classic (``ColorChecker N Ohta`` spectra, chart order) on the back
wall, visible from both camera views. The seed varies room size, wall/floor spectra (drawn from the
CIE 2017 colour-fidelity samples), object placement, sun direction and light strengths.

``validation_chart()`` — 24 Lambertian patches facing the camera head-on under one directional
light, no other geometry: the closed form of every patch's radiance is ``S̄ · E · cosθ / π``.
"""

from __future__ import annotations

import math

import numpy as np

from illumix.scene.load import scene_from_dict
from illumix.scene.model import Scene

CHART_SET = "ColorChecker N Ohta"
CHART_ROWS, CHART_COLS = 4, 6


def frame_matrix(center, normal, up, size) -> list[list[float]]:
    """4×4 matrix placing Mitsuba's canonical rectangle ``[-1, 1]²`` (normal +z) at ``center``
    facing ``normal`` with its local +y along ``up`` (projected), ``size = (width, height)`` metres."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    u = np.asarray(up, dtype=float)
    u = u - n * np.dot(u, n)
    u = u / np.linalg.norm(u)
    r = np.cross(u, n)
    m = np.eye(4)
    m[:3, 0] = r * size[0] / 2
    m[:3, 1] = u * size[1] / 2
    m[:3, 2] = n
    m[:3, 3] = center
    return m.round(9).tolist()


def box_matrix(center, half_extents) -> list[list[float]]:
    """4×4 matrix placing Mitsuba's cube ``[-1, 1]³`` axis-aligned at ``center``."""
    m = np.diag([*half_extents, 1.0])
    m[:3, 3] = center
    return m.round(9).tolist()


def chart_patch_centers(center, normal, up, patch: float, gap: float) -> list[np.ndarray]:
    """Centres of the 24 patches in chart order (row-major from the top left, as seen facing it)."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    u = np.asarray(up, dtype=float)
    u = u - n * np.dot(u, n)
    u = u / np.linalg.norm(u)
    r = np.cross(u, n)  # viewer's right when looking at the chart's face
    pitch = patch + gap
    out = []
    for row in range(CHART_ROWS):
        for col in range(CHART_COLS):
            dx = (col - (CHART_COLS - 1) / 2) * pitch
            dy = ((CHART_ROWS - 1) / 2 - row) * pitch
            out.append(np.asarray(center, dtype=float) + dx * r + dy * u)
    return out


def colorchecker(center, normal, up=(0, 1, 0), patch: float = 0.1, gap: float = 0.02,
                 prefix: str = "cc", backing: bool = True) -> tuple[dict, list[dict]]:
    """Materials and shapes of a ColorChecker Classic: 24 patch rectangles (``{prefix}_01`` …
    ``{prefix}_24``) just in front of an optional dark backing board."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    materials = {f"{prefix}_{i + 1:02d}": {"kind": "diffuse", "reflectance": {"library": CHART_SET, "index": i}}
                 for i in range(24)}
    shapes = []
    for i, c in enumerate(chart_patch_centers(center, n, up, patch, gap)):
        shapes.append({"name": f"{prefix}_{i + 1:02d}", "type": "rectangle", "material": f"{prefix}_{i + 1:02d}",
                       "transform": {"matrix": frame_matrix(c + 0.004 * n, n, up, (patch, patch))}})
    if backing:
        materials[f"{prefix}_board"] = {"kind": "diffuse", "reflectance": {"value": 0.04}}
        w = CHART_COLS * (patch + gap) + gap
        h = CHART_ROWS * (patch + gap) + gap
        shapes.append({"name": f"{prefix}_board", "type": "rectangle", "material": f"{prefix}_board",
                       "transform": {"matrix": frame_matrix(np.asarray(center) + 0.002 * n, n, up, (w, h))}})
    return materials, shapes


def _pale_samples(rng: np.random.Generator, k: int, lo: float, max_chroma: float = 10.0) -> list[int]:
    """``k`` distinct CIE 2017 sample indices with mean reflectance ≥ ``lo`` and relative spectral
    spread (std / mean over the grid) ≤ ``max_chroma``."""
    from illumix.retarget.reflectances import get_reflectances

    _, r = get_reflectances("CIE 2017")
    m = r.mean(axis=1)
    idx = np.flatnonzero((m >= lo) & (r.std(axis=1) / m <= max_chroma))
    return [int(i) for i in rng.choice(idx, size=k, replace=False)]


def demo_room_dict(seed: int = 0, resolution: tuple[int, int] = (320, 240), name: str | None = None) -> dict:
    """The demo room as a plain document (see module docstring); deterministic in ``seed``."""
    # The helpers draw from ``rng`` in a fixed order (room, materials, window, furniture, chart,
    # emitters, lights): reordering the calls changes every seed's room.
    rng = np.random.default_rng(seed)
    w = float(rng.uniform(4.5, 5.5))   # x extent
    d = float(rng.uniform(4.5, 5.5))   # z extent
    h = float(rng.uniform(2.6, 2.9))   # ceiling height
    x0, x1, z0, z1 = -w / 2, w / 2, -d / 2, d / 2

    materials = _room_materials(rng)
    shapes = _room_shell(w, d, h)
    window_shapes, win_y, win_z = _left_wall_with_window(rng, x0, z0, z1, h)
    shapes += window_shapes
    # Furniture and objects.
    tx, tz = float(rng.uniform(0.3, 1.0)), float(rng.uniform(-0.8, 0.2))
    table_top = 0.75
    shapes += _furniture(rng, tx, tz, table_top)
    # Chart on the back wall, facing the room.
    chart_mats, chart_shapes = colorchecker(center=(float(rng.uniform(-0.6, 0.2)), 1.35, z0 + 0.005),
                                            normal=(0, 0, 1), patch=0.14, gap=0.025)
    materials.update(chart_mats)
    shapes += chart_shapes
    shapes += _room_emitters(rng, h, x0, win_y, win_z)
    desk_target = (float(chart_shapes[0]["transform"]["matrix"][0][3]) + 0.3, 1.3, z0)
    lights = _room_lights(rng, tx, tz, table_top, desk_target)
    aspect_views = [
        {"name": "front", "origin": (0.2, 1.5, z1 - 0.4), "target": (-0.2, 1.1, z0), "fov": 70.0},
        {"name": "corner", "origin": (x1 - 0.4, 1.7, z1 - 0.6), "target": (-0.9, 0.9, z0 + 0.6), "fov": 75.0},
    ]
    views = [{**v, "up": (0, 1, 0), "resolution": tuple(resolution)} for v in aspect_views]
    return {
        "name": name or f"demo-room-{seed}",
        "description": f"procedural demo room, seed {seed}",
        "materials": materials,
        "shapes": shapes,
        "lights": lights,
        "light_groups": [
            {"name": "daylight", "kind": "daylight", "description": "sun through the window + sky"},
            {"name": "ceiling", "kind": "artificial", "description": "ceiling panel"},
            {"name": "desk", "kind": "artificial", "description": "spot lamp on the table"},
        ],
        "views": views,
        "max_depth": 8,
    }


def _room_materials(rng: np.random.Generator) -> dict:
    """The room's own materials (walls, floor, furniture, objects; not the chart's)."""
    walls = _pale_samples(rng, 2, 0.4, max_chroma=0.25)
    (floor_idx,) = [int(i) for i in rng.choice(_dark_floor_candidates(), size=1)]
    ball_idx, table_idx = _pale_samples(rng, 2, 0.15)
    return {
        "wall_a": {"kind": "diffuse", "reflectance": {"library": "CIE 2017", "index": walls[0]}},
        "wall_b": {"kind": "diffuse", "reflectance": {"library": "CIE 2017", "index": walls[1]}},
        "ceiling": {"kind": "diffuse", "reflectance": {"value": 0.8}},
        "floor": {"kind": "roughplastic", "reflectance": {"library": "CIE 2017", "index": floor_idx},
                  "alpha": 0.25},
        "table": {"kind": "diffuse", "reflectance": {"library": "CIE 2017", "index": table_idx}},
        "ball": {"kind": "roughplastic", "reflectance": {"library": "CIE 2017", "index": ball_idx},
                 "alpha": 0.08},
        "metal": {"kind": "roughconductor", "conductor": "Al", "alpha": 0.2},
        "glass": {"kind": "dielectric", "int_ior": 1.5},
        "lamp_housing": {"kind": "diffuse", "reflectance": {"value": 0.5}},
    }


def _room_shell(w: float, d: float, h: float) -> list[dict]:
    """Floor, ceiling and the three walls without the window (back, front, right)."""
    x1, z0, z1 = w / 2, -d / 2, d / 2
    up = (0, 1, 0)
    return [
        {"name": "floor", "type": "rectangle", "material": "floor",
         "transform": {"matrix": frame_matrix((0, 0, 0), (0, 1, 0), (0, 0, -1), (w, d))}},
        {"name": "ceiling", "type": "rectangle", "material": "ceiling",
         "transform": {"matrix": frame_matrix((0, h, 0), (0, -1, 0), (0, 0, -1), (w, d))}},
        {"name": "wall_back", "type": "rectangle", "material": "wall_a",
         "transform": {"matrix": frame_matrix((0, h / 2, z0), (0, 0, 1), up, (w, h))}},
        {"name": "wall_front", "type": "rectangle", "material": "wall_a",
         "transform": {"matrix": frame_matrix((0, h / 2, z1), (0, 0, -1), up, (w, h))}},
        {"name": "wall_right", "type": "rectangle", "material": "wall_b",
         "transform": {"matrix": frame_matrix((x1, h / 2, 0), (-1, 0, 0), up, (d, h))}},
    ]


def _left_wall_with_window(rng: np.random.Generator, x0: float, z0: float, z1: float,
                           h: float) -> tuple[list[dict], tuple[float, float], tuple[float, float]]:
    """``(shapes, (y0, y1), (z0, z1))``: the left wall's pieces and the window opening's extent."""
    up = (0, 1, 0)
    shapes = []
    # Left wall (x = x0, facing +x) with a window opening: four rectangles around the hole.
    win_z = (float(rng.uniform(z0 + 1.0, -0.6)), 0.0)
    win_z = (win_z[0], win_z[0] + float(rng.uniform(1.2, 1.6)))
    win_y = (0.9, min(h - 0.3, 2.3))
    pieces = {
        "wall_left_below": ((z0, z1), (0.0, win_y[0])),
        "wall_left_above": ((z0, z1), (win_y[1], h)),
        "wall_left_back": ((z0, win_z[0]), win_y),
        "wall_left_front": ((win_z[1], z1), win_y),
    }
    for nm, ((za, zb), (ya, yb)) in pieces.items():
        shapes.append({"name": nm, "type": "rectangle", "material": "wall_b",
                       "transform": {"matrix": frame_matrix((x0, (ya + yb) / 2, (za + zb) / 2), (1, 0, 0), up,
                                                            (zb - za, yb - ya))}})
    return shapes, win_y, win_z


def _furniture(rng: np.random.Generator, tx: float, tz: float, table_top: float) -> list[dict]:
    """The table at ``(tx, tz)`` with the ball and the can on it, and the glass ball on the floor."""
    return [
        {"name": "table", "type": "cube", "material": "table",
         "transform": {"matrix": box_matrix((tx, table_top / 2, tz), (0.6, table_top / 2, 0.45))}},
        {"name": "ball", "type": "sphere", "material": "ball",
         "center": (tx - 0.25, table_top + 0.18, tz + 0.1), "radius": 0.18},
        {"name": "can", "type": "cylinder", "material": "metal",
         "p0": (tx + 0.3, table_top, tz - 0.15), "p1": (tx + 0.3, table_top + 0.3, tz - 0.15), "radius": 0.08},
        {"name": "can_lid", "type": "disk", "material": "metal",
         "transform": {"matrix": frame_matrix((tx + 0.3, table_top + 0.3, tz - 0.15), (0, 1, 0), (0, 0, -1),
                                              (0.16, 0.16))}},
        {"name": "glass_ball", "type": "sphere", "material": "glass",
         "center": (float(rng.uniform(-1.2, -0.4)), 0.15, float(rng.uniform(-0.5, 0.5))), "radius": 0.15},
    ]


def _room_emitters(rng: np.random.Generator, h: float, x0: float, win_y: tuple[float, float],
                   win_z: tuple[float, float]) -> list[dict]:
    """The emitting shapes: the ceiling panel and the sky portal in the window."""
    up = (0, 1, 0)
    # Ceiling panel light (one-sided area emitter facing down) with a housing above it.
    shapes = [
        {"name": "ceiling_panel", "type": "rectangle",
         "emitter": {"group": "ceiling", "strength": round(float(rng.uniform(3.0, 5.0)), 3)},
         "transform": {"matrix": frame_matrix((0.3, h - 0.02, 0.3), (0, -1, 0), (0, 0, -1), (0.8, 0.8))}},
    ]
    # The sky seen through the window: a portal filling the opening, emitting the (uniform) sky
    # radiance into the room — exact for a constant sky, and sampled far better than the sphere.
    shapes.append({"name": "window_sky", "type": "rectangle",
                   "emitter": {"group": "daylight", "strength": round(float(rng.uniform(0.6, 1.0)), 3), "portal": True},
                   "transform": {"matrix": frame_matrix((x0, (win_y[0] + win_y[1]) / 2, (win_z[0] + win_z[1]) / 2),
                                                        (1, 0, 0), up, (win_z[1] - win_z[0], win_y[1] - win_y[0]))}})
    return shapes


def _room_lights(rng: np.random.Generator, tx: float, tz: float, table_top: float, desk_target) -> list[dict]:
    """The sun through the window and the desk spot (aimed at ``desk_target``, beside the chart)."""
    # Sun through the window: travelling into the room (+x), downwards.
    elev = math.radians(float(rng.uniform(25, 40)))
    azim = math.radians(float(rng.uniform(-25, 25)))
    sun_dir = (math.cos(elev) * math.cos(azim), -math.sin(elev), math.cos(elev) * math.sin(azim))
    return [
        {"name": "sun", "type": "directional", "group": "daylight", "direction": [round(v, 6) for v in sun_dir],
         "strength": round(float(rng.uniform(4.0, 6.0)), 3)},
        {"name": "desk_spot", "type": "spot", "group": "desk",
         "position": (tx - 0.4, table_top + 0.6, tz + 0.3),
         "target": desk_target,
         "cutoff_angle": 35.0, "beam_width": 25.0, "strength": round(float(rng.uniform(2.0, 3.0)), 3)},
    ]


def _dark_floor_candidates() -> list[int]:
    from illumix.retarget.reflectances import get_reflectances

    _, r = get_reflectances("CIE 2017")
    m = r.mean(axis=1)
    return [int(i) for i in np.flatnonzero((m > 0.12) & (m < 0.35))]


def demo_room(seed: int = 0, resolution: tuple[int, int] = (320, 240), name: str | None = None) -> Scene:
    """The demo room as a validated :class:`Scene`."""
    return scene_from_dict(demo_room_dict(seed, resolution, name), source=f"demo room (seed {seed})")


# Validation chart -----------------------------------------------------------------------------

VALIDATION_PATCH = 0.1
VALIDATION_GAP = 0.04


def validation_chart_dict(resolution: tuple[int, int] = (96, 64), incidence_deg: float = 30.0,
                          emission: str = "flat", name: str = "validation-chart") -> dict:
    """24 Lambertian ColorChecker patches in the z = 0 plane facing +z (no backing, no other
    geometry), seen head-on by a camera on the +z axis, lit by one directional light (irradiance 1 on
    a plane perpendicular to it) arriving at ``incidence_deg`` from the normal."""
    mats, shapes = colorchecker(center=(0, 0, 0), normal=(0, 0, 1), patch=VALIDATION_PATCH,
                                gap=VALIDATION_GAP, prefix="p", backing=False)
    th = math.radians(incidence_deg)
    w = CHART_COLS * (VALIDATION_PATCH + VALIDATION_GAP)
    dist = 3.0
    fov = 2 * math.degrees(math.atan(0.5 * w * 1.08 / dist))
    return {
        "name": name,
        "description": "closed-form validation: Lambertian ColorChecker under a distant light",
        "materials": {k: {**v, "two_sided": False} for k, v in mats.items()},
        "shapes": shapes,
        "lights": [{"name": "sun", "type": "directional", "group": "light",
                    "direction": (0.0, -math.sin(th), -math.cos(th)), "strength": 1.0}],
        "light_groups": [{"name": "light", "emission": emission}],
        "views": [{"name": "head-on", "origin": (0, 0, dist), "target": (0, 0, 0), "up": (0, 1, 0),
                   "fov": fov, "resolution": tuple(resolution)}],
        "max_depth": 4,
    }


def validation_chart(resolution: tuple[int, int] = (96, 64), incidence_deg: float = 30.0,
                     emission: str = "flat") -> Scene:
    return scene_from_dict(validation_chart_dict(resolution, incidence_deg, emission),
                           source="validation chart")
