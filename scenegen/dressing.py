"""Dressing: what turns placed furniture into a lived-in room — window joinery and curtains, door
casings, a closed door in an outer wall, something on every wall, something on every top, and a
floor of planks or tiles.

Runs after furniture, lights and clutter (:mod:`scenegen.generate`), through the same
:class:`scenegen.placement.Placer`, so nothing it adds intersects what is there:

- **windows**: a casing, a sash frame (mullion, transom) and a sill at every window (placed before
  the furniture, which keeps clear of them); **doorways**: a casing on both faces of a partition's
  door opening;
- **curtains**: most windows get a pair on a rod, to the floor where the floor in front is free,
  else to just below the sill;
- **kitchens**: wall units over each counter;
- **doors**: each room gets a closed door (frame, panels, lever handle) in an outer wall, with the
  floor in front of it kept clear;
Shapes are named like clutter (:mod:`scenegen.generate`): ``d{n}_<kind>{n}_…`` on walls,
``t{n}_<kind>{n}_…`` on tops, ``curtain{k}_…``, ``exit{room}_…`` (doors), ``floor{i}_…``.

- **walls**: a wall with nothing on it (no opening, nothing standing or hung against it) gets a
  picture, a wall shelf or a clock, a long one two;
- **tops**: every free top (tables, desks, cabinets, counters, wall shelves, bookcases) with nothing
  on it gets one to three things;
- **floors**: the floor rectangles become meshes with texture coordinates in metres — boards of
  random length in staggered rows when the floor is wood (each cut from another part of the
  grain), one sheet otherwise — so the floor's texture has its physical size.
"""

from __future__ import annotations

import numpy as np

from illumix.scenegen import mesh as M
from illumix.scenegen.meshparts import Parts
from illumix.scenegen.parts import Item, place
from illumix.scenegen.placement import quarter_turns_facing
from illumix.scenegen.rooms import DOOR, PARTITION

def window_frames(rng, plan, placer, mats, windows) -> list[dict]:
    """Each window's joinery on the room side of its opening: a moulded casing round it, a sash
    frame in it (a mullion when it is wide, a transom when it is tall), a sill board under it. The
    casing's span is kept on its wall (tall furniture stays clear; curtains may cover it)."""
    out = []
    mat = mats.pick(str(rng.choice(["white", "white", "paint", "wood"])))
    for k, (wi, o) in enumerate(windows):
        w, h = o.s1 - o.s0, o.y1 - o.y0
        p = Parts(f"window{k}")
        p.add(mat, M.frame_ring(w, h, [(0, 0), (0.065, 0), (0.065, 0.012), (0.05, 0.02), (0, 0.022)]).at(0, o.y0 + h / 2, 0))
        p.add(mat, M.frame_ring(w - 0.1, h - 0.1, [(0, 0), (0.05, 0), (0.05, 0.05), (0, 0.05)]).at(0, o.y0 + h / 2, 0))
        if w > 1.0:
            p.add(mat, M.box((0, o.y0 + h / 2, 0.025), (0.025, h / 2 - 0.05, 0.025)))
        if h > 1.2:
            p.add(mat, M.box((0, o.y0 + h * 0.7, 0.02), (w / 2 - 0.05, 0.022, 0.02)))
        p.add(mat, M.bevel_box((0, o.y0 - 0.0125, 0.07), (w / 2 + 0.09, 0.0125, 0.07), 0.003))
        wall = plan.walls[wi]
        c = wall.point((o.s0 + o.s1) / 2)
        out += place(Item("window", p.shapes(), (w, 0.14), h), float(c[0]), float(c[1]), quarter_turns_facing(wall.normal), "")
        placer.opening_spans.add((wi, o.s0 - 0.075, o.s1 + 0.075, o.y0 - 0.05, o.y1 + 0.075))
        placer.wall_spans.setdefault(wi, []).append((o.s0 - 0.075, o.s1 + 0.075, o.y0 - 0.05, o.y1 + 0.075))
    return out


def doorways(plan, mats, material: str) -> list[dict]:
    """A casing round the doorway between two rooms, on both faces of the partition."""
    out = []
    for i, (lo, hi, n) in enumerate(plan.doors):
        width = float(np.linalg.norm(hi - lo))
        ring = M.frame_ring(width, DOOR[1] + 0.06, [(0, 0), (0.07, 0), (0.07, 0.012), (0.055, 0.02), (0, 0.022)])
        mid = (lo + hi) / 2
        for side in (-1.0, 1.0):
            p = Parts(f"door{i}")
            p.add(material, ring.at(0, DOOR[1] / 2 - 0.03, 0))
            normal = (side * float(n[0]), side * float(n[1]))
            c = mid + np.asarray(normal) * PARTITION / 2
            out += [dict(s, name=f"door{i}_casing{int(side > 0)}{s['name'][len(f'door{i}'):]}") for s in
                    place(Item("casing", p.shapes(), (width, 0.03), DOOR[1]), float(c[0]), float(c[1]),
                          quarter_turns_facing(normal), "")]
    return out


WALL_TRIES = (("frame", (1.3, 1.7)), ("wall_shelf", (1.05, 1.45)), ("frame", (1.2, 1.6)), ("clock", (1.6, 1.9)))


def curtains(rng, plan, placer, mats, windows) -> list[dict]:
    """Curtains for most windows (see module docstring)."""
    from illumix.scenegen.catalog import CURTAIN

    out = []
    for k, (wi, o) in enumerate(windows):
        if rng.random() < 0.15:  # a bare window now and then
            continue
        top = min(plan.height - 0.03, o.y1 + 0.15)
        mid = (o.s0 + o.s1) / 2
        for extra, y0 in ((0.3, 0.01), (0.3, o.y0 - 0.04), (0.1, o.y0 - 0.04)):
            item = CURTAIN(rng, mats, f"curtain{k}", o.s1 - o.s0 + extra, top - y0)
            got = placer.at_wall(item, f"curtain{k}", wi, mid - item.footprint[0] / 2, y0, gap=0.15,  # clear of the sill
                                 over_openings=True)
            if got:
                out += got
                break
    return out


def kitchen_wall_units(rng, plan, placer, mats) -> list[dict]:
    """Wall units above each kitchen counter (bottom 1.45–1.55 m, up to 30 cm under the ceiling),
    where no window or hung thing is in the way."""
    from illumix.scenegen.catalog import WALL_CABINET

    out = []
    for n, p in enumerate([p for p in placer.placed if p.kind == "kitchen_counter"]):
        for wi, w in enumerate(plan.walls):
            if quarter_turns_facing(w.normal) != p.turns:
                continue
            rel = np.array([p.x, p.z]) - np.asarray(w.p0)
            back = float(rel @ np.asarray(w.normal)) - p.item.footprint[1] / 2
            s = float(rel @ w.direction)
            if not (0 <= back < 0.2 and 0 <= s <= w.length):
                continue
            y0 = float(rng.uniform(1.45, 1.55))
            height = min(0.75, plan.height - 0.3 - y0)
            if height < 0.4:
                break
            item = WALL_CABINET(rng, mats, f"wallunit{n}", p.item.footprint[0] - 0.02, height)
            out += placer.at_wall(item, f"wallunit{n}", wi, s - item.footprint[0] / 2, y0) or []
            break
    return out


def doors(rng, plan, placer, mats) -> list[dict]:
    """A closed door in an outer wall of each room, where one fits."""
    from illumix.scenegen.catalog import DOOR

    out = []
    for room in sorted(set(plan.rooms)):
        walls = [i for i, w in enumerate(plan.walls) if not w.partition and w.room == room and w.length > 1.5]
        if not walls or rng.random() < 0.1:
            continue
        item = DOOR(rng, mats, f"exit{room}")
        for _ in range(20):
            wi = walls[int(rng.integers(len(walls)))]
            w = plan.walls[wi]
            s0 = float(rng.uniform(0.15, max(0.16, w.length - item.footprint[0] - 0.15)))
            if not w.free(s0, s0 + item.footprint[0], margin=0.1):
                continue
            got = placer.at_wall(item, f"exit{room}", wi, s0, 0.0, keep=0.7)
            if got:
                out += got
                break
    return out


def walls(rng, plan, placer, mats) -> list[dict]:
    """Something on every wall that has nothing (see module docstring)."""
    from illumix.scenegen.catalog import CLUTTER

    out, n = [], 0
    for wi, w in enumerate(plan.walls):
        if w.length < 0.9 or w.openings or placer.wall_spans.get(wi):
            continue
        tries = (WALL_TRIES[int(j)] for j in rng.permutation(len(WALL_TRIES)))
        n = _place_some(tries, 2 if w.length > 3.2 else 1, "d", n, out,
                        lambda t, name: placer.hang(CLUTTER[t[0]](rng, mats, name), name, t[1], tries=12, walls=[wi]),
                        kind=lambda t: t[0])
    return out


def tops(rng, placer, mats) -> list[dict]:
    """One to three things on every free top that has nothing on it."""
    from illumix.scenegen.catalog import CLUTTER, TABLETOP

    out, n = [], 0
    for s in list(placer.surfaces):
        if s.taken:
            continue
        want = 1 + int(s.size[0] * s.size[1] > 0.5) + int(rng.random() < 0.5)
        kinds = (TABLETOP[int(rng.integers(len(TABLETOP)))] for _ in range(want * 3))  # drawn as tried
        n = _place_some(kinds, want, "t", n, out,
                        lambda kind, name, s=s: placer.on_surface(CLUTTER[kind](rng, mats, name), name, tries=6, only=s))
    return out


def _place_some(tries, want: int, prefix: str, n: int, out: list, place, kind=lambda t: t) -> int:
    """Place up to ``want`` things, trying ``tries`` in order (lazily: a try's random numbers are drawn
    only when it is reached); ``place(try, name)`` returns the shapes or nothing. Placed shapes are
    renamed ``{prefix}{n}_…`` and appended to ``out``; returns the next ``n``."""
    for t in tries:
        name = f"{kind(t).replace('_', '-')}{n}"
        got = place(t, name)
        if got:
            out += [dict(sh, name=f"{prefix}{n}_{sh['name']}") for sh in got]
            n += 1
            want -= 1
            if want == 0:
                break
    return n


def _quad(x0: float, z0: float, x1: float, z1: float, y: float = 0.0) -> M.Mesh:
    v = np.array([(x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1)], float)
    return M.Mesh(v, np.array([[0, 3, 2], [0, 2, 1]]), np.tile([0.0, 1.0, 0.0], (4, 1)))


def floors(rng, plan, material: str, wood: bool) -> list[dict]:
    """The floor rectangles as meshes (see module docstring), named ``floor{i}_…``."""
    out = []
    for i, (x0, z0, x1, z1) in enumerate(plan.rects):
        p = Parts(f"floor{i}")
        if not wood:
            p.add(material, _quad(x0, z0, x1, z1))
        else:  # boards along z (the grain's direction in texture space), rows across x
            bw = float(rng.uniform(0.12, 0.22))
            xs = np.append(np.arange(x0, x1, bw), x1)
            for a, b in zip(xs[:-1], xs[1:]):
                z = z0 - float(rng.uniform(0, 1.2))
                while z < z1:
                    ln = float(rng.uniform(0.9, 2.1))
                    za, zb = max(z, z0), min(z + ln, z1)
                    if zb - za > 1e-4:
                        p.add(material, _quad(a, za, b, zb), uv_offset=(float(rng.uniform(0, 8)), float(rng.uniform(0, 8))))
                    z += ln
        out += p.shapes()
    return out
