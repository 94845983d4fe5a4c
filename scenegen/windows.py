"""Windows and daylight: openings in the outer walls, the sky seen through them and the sun.

``add_windows`` cuts 0–3 windows (varied width, sill and head height) into exterior walls long
enough to hold them. Daylight is one light group (``daylight``) at a daylight CCT
(``daylight:<K>``, 5000–7500 K): a **sky portal** filling each window (a Lambertian emitter of the
sky's radiance — exact for a uniform sky, see :class:`scene.schema.AreaEmission`) and
a **sun** (directional) arriving through one of the windows, 20–55° above the horizon and within
±35° of that window's normal, so that a sunlit patch lands inside the room.
"""

from __future__ import annotations

import math

import numpy as np

from illumix.scenegen.parts import rect
from illumix.scenegen.rooms import Opening, Plan


def add_windows(rng: np.random.Generator, plan: Plan, count: int) -> list[tuple[int, Opening]]:
    """Cut up to ``count`` windows into exterior walls; returns ``(wall index, opening)`` pairs."""
    out: list[tuple[int, Opening]] = []
    h = plan.height
    for _ in range(count * 4):  # a few tries per window
        if len(out) == count:
            break
        cands = [i for i, w in enumerate(plan.walls) if not w.partition and w.length >= 1.6]
        if not cands:
            break
        i = int(rng.choice(cands))
        w = plan.walls[i]
        width = float(rng.uniform(0.8, min(2.4, w.length - 0.6)))
        s0 = float(rng.uniform(0.3, w.length - 0.3 - width))
        sill = float(rng.uniform(0.5, 1.0))
        head = float(min(h - 0.2, rng.uniform(1.9, 2.4)))
        if head - sill < 0.6 or not w.free(s0, s0 + width, margin=0.25):
            continue
        o = Opening(round(s0, 4), round(s0 + width, 4), round(sill, 4), round(head, 4), "window")
        w.openings.append(o)
        out.append((i, o))
    return out


def daylight(rng: np.random.Generator, plan: Plan, windows: list[tuple[int, Opening]],
             group: str = "daylight") -> tuple[list[dict], list[dict], dict]:
    """``(portal shapes, [sun light], light group)`` for the windows (none without windows)."""
    if not windows:
        return [], [], {}
    cct = int(round(float(rng.uniform(5000, 7500)), -2))
    sky = round(float(rng.uniform(0.4, 1.2)), 3)
    shapes = []
    for k, (i, o) in enumerate(windows):
        w = plan.walls[i]
        mid = w.point((o.s0 + o.s1) / 2)
        shapes.append(rect(f"window{k}_sky", None, (mid[0], (o.y0 + o.y1) / 2, mid[1]),
                           (w.normal[0], 0.0, w.normal[1]), (0, 1, 0), (o.s1 - o.s0, o.y1 - o.y0),
                           emitter={"group": group, "strength": sky, "portal": True}))
    i, o = windows[int(rng.integers(len(windows)))]
    n = plan.walls[i].normal
    elev = math.radians(float(rng.uniform(20, 55)))
    azim = math.radians(float(rng.uniform(-35, 35)))
    # travelling into the room: along the inward normal, turned by azim about y, and down
    hx = n[0] * math.cos(azim) - n[1] * math.sin(azim)
    hz = n[0] * math.sin(azim) + n[1] * math.cos(azim)
    direction = [round(math.cos(elev) * hx, 6), round(-math.sin(elev), 6), round(math.cos(elev) * hz, 6)]
    sun = {"name": "sun", "type": "directional", "group": group, "direction": direction,
           "strength": round(float(rng.uniform(3.0, 8.0)), 3)}
    grp = {"name": group, "emission": f"daylight:{cct}", "kind": "daylight",
           "description": f"sun + sky through {len(windows)} window(s), CIE daylight {cct} K"}
    return shapes, [sun], grp
