"""The catalogue: every piece of furniture and clutter the generator can build, by name.

``FURNITURE`` and ``CLUTTER`` map a kind to its builder ``(rng, mats, name) -> Item``
(:mod:`scenegen.meshfurniture`, :mod:`scenegen.appliances`, :mod:`scenegen.meshclutter`): triangle
meshes with real detail, wrapped by :func:`fitted` so that an item's footprint and height cover its
geometry (what placement keeps apart). ``TABLETOP`` names what stands on tops, ``WALL_ITEMS`` what
hangs on walls, ``FLOOR_CLUTTER`` what lies or stands on the floor (a rug is placed anywhere and may
lie under furniture; the rest stands against a wall); ``DOOR``, ``CURTAIN`` and ``WALL_CABINET`` are placed by the
dressing pass (:mod:`scenegen.dressing`).
"""

from __future__ import annotations

import functools

import numpy as np

from illumix.scenegen import appliances as ap
from illumix.scenegen import meshclutter as mc
from illumix.scenegen import meshfurniture as mf
from illumix.scenegen.parts import Item


def geometry_bounds(item: Item) -> tuple[np.ndarray, np.ndarray]:
    """``(lo (3,), hi (3,))`` of an item's shapes in its own frame (meshes by their files' bounds,
    primitives from their parameters)."""
    from illumix.scenegen.meshparts import mesh_bounds

    pts = []
    for s in item.shapes:
        if s["type"] == "ply":
            m = np.asarray(s["transform"]["matrix"], float)
            b = mesh_bounds(s["filename"])
            corners = np.array([[x, y, z] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]])
            pts.append(corners @ m[:3, :3].T + m[:3, 3])
        elif s["type"] == "sphere":
            c, r = np.asarray(s["center"]), s["radius"]
            pts.append(np.array([c - r, c + r]))
        elif "transform" in s:
            m = np.asarray(s["transform"]["matrix"], float)
            corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
            if s["type"] != "cube":
                corners[:, 2] = 0.0
            pts.append((corners @ m.T)[:, :3])
    p = np.concatenate(pts)
    return p.min(axis=0), p.max(axis=0)


def fitted(build):
    """``build`` with the item's footprint (centred on its origin) and height grown to cover its
    geometry: handles, knobs and leaves never reach past what placement reserves."""

    @functools.wraps(build)
    def wrapper(rng, mats, name, *args) -> Item:
        item = build(rng, mats, name, *args)
        lo, hi = geometry_bounds(item)
        w = max(item.footprint[0], 2 * float(max(-lo[0], hi[0])) + 0.002)
        d = max(item.footprint[1], 2 * float(max(-lo[2], hi[2])) + 0.002)
        item.footprint = (round(w, 4), round(d, 4))
        item.height = round(max(item.height, float(hi[1]) + 0.002), 4)
        return item

    return wrapper


FURNITURE = {k: fitted(f) for k, f in {
    "table": mf.table, "coffee_table": mf.coffee_table, "desk": mf.desk, "chair": mf.chair, "sofa": mf.sofa, "cabinet": mf.cabinet,
    "shelf": mf.shelf, "bed": ap.bed, "kitchen_counter": ap.kitchen_counter, "fridge": ap.fridge,
    "oven": ap.oven, "washing_machine": ap.washing_machine}.items()}
_TABLETOP = {"cup": mc.cup, "bottle": mc.bottle, "bowl": mc.bowl, "plant": mc.plant, "vase": mc.vase,
             "book_stack": mc.book_stack, "box": mc.storage_box}
_WALL = {"frame": mc.frame, "clock": mc.clock, "wall_shelf": mc.wall_shelf}
_FLOOR = {"rug": mc.rug, "floor_plant": mc.floor_plant}
CLUTTER = {k: fitted(f) for k, f in {**_TABLETOP, **_WALL, **_FLOOR}.items()}
DOOR = fitted(ap.door)
WALL_CABINET = fitted(ap.wall_cabinet)
CURTAIN = fitted(mc.curtain)
TABLETOP = sorted(_TABLETOP)
WALL_ITEMS = sorted(_WALL)
FLOOR_CLUTTER = sorted(_FLOOR)
