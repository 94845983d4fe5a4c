"""Clutter built from parametric parts: what stands on tables, shelves and counters (mugs, bottles,
bowls of fruit, plants, vases, book stacks, boxes), what hangs on walls (pictures, clocks) and what
lies or stands on the floor (rugs, large plants).

Builders are ``(rng, mats, name) -> Item`` in the item's own frame (:mod:`scenegen.parts`: origin at
the centre of the footprint, ``y = 0`` the surface it stands on, front ``+z``). Hung items have their
back at ``-z`` against the wall. Open cylinders are capped with disks where the inside would show.
"""

from __future__ import annotations

import math

from illumix.scenegen.parts import Item, MaterialPicker, box, cylinder, disk, rect, sphere


def _u(rng, lo: float, hi: float) -> float:
    return round(float(rng.uniform(lo, hi)), 4)


def mug(rng, mats: MaterialPicker, name: str) -> Item:
    r, h = _u(rng, 0.035, 0.045), _u(rng, 0.08, 0.1)
    m = mats.pick("ceramic")
    return Item("mug", [cylinder(f"{name}_body", m, (0, 0, 0), (0, h, 0), r),
                        disk(f"{name}_bottom", m, (0, 0.006, 0), (0, 1, 0), r),
                        box(f"{name}_handle", m, (r + 0.012, h / 2, 0), (0.012, h / 3, 0.006))],
                (2 * r + 0.05, 2 * r), h)


def bottle(rng, mats: MaterialPicker, name: str) -> Item:
    r, h = _u(rng, 0.03, 0.045), _u(rng, 0.2, 0.32)
    body = mats.pick(str(rng.choice(["glass", "glass", "plastic"])))
    cap = mats.pick(str(rng.choice(["metal", "plastic", "black"])))
    neck = h * 0.3
    return Item("bottle", [cylinder(f"{name}_body", body, (0, 0, 0), (0, h - neck, 0), r),
                           disk(f"{name}_shoulder", body, (0, h - neck, 0), (0, 1, 0), r),
                           disk(f"{name}_base", body, (0, 0.001, 0), (0, -1, 0), r),
                           cylinder(f"{name}_neck", body, (0, h - neck, 0), (0, h - 0.02, 0), 0.013),
                           cylinder(f"{name}_cap", cap, (0, h - 0.02, 0), (0, h, 0), 0.015),
                           disk(f"{name}_captop", cap, (0, h, 0), (0, 1, 0), 0.015)],
                (2 * r, 2 * r), h)


def bowl(rng, mats: MaterialPicker, name: str) -> Item:
    """A shallow bowl with 0–5 pieces of fruit (food spectra)."""
    r, h = _u(rng, 0.09, 0.15), _u(rng, 0.05, 0.08)
    m = mats.pick("ceramic")
    shapes = [cylinder(f"{name}_wall", m, (0, 0, 0), (0, h, 0), r),
              disk(f"{name}_floor", m, (0, 0.008, 0), (0, 1, 0), r)]
    for i in range(int(rng.integers(0, 6))):
        fr = _u(rng, 0.03, 0.045)
        a, d = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(0, r - fr - 0.005))
        y = 0.008 + fr + (0.05 if i >= 3 else 0.0)  # the last two lie on the first three
        shapes.append(sphere(f"{name}_fruit{i}", mats.pick("food"), (d * math.cos(a), y, d * math.sin(a)), fr))
    return Item("bowl", shapes, (2 * r, 2 * r), h + 0.1)


def _foliage(rng, mats: MaterialPicker, name: str, centre: tuple[float, float, float], spread: float,
             n: int, size: tuple[float, float]) -> list[dict]:
    """A bush: ``n`` leaf clusters (spheres of plant spectra) around ``centre``."""
    leaf = [mats.pick("plant") for _ in range(2)]
    out = []
    for i in range(n):
        a, e = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(-0.3, 1.0))
        d = float(rng.uniform(0.2, 1.0)) * spread
        p = (centre[0] + d * math.cos(a) * math.cos(e), centre[1] + d * math.sin(e) * 0.8,
             centre[2] + d * math.sin(a) * math.cos(e))
        out.append(sphere(f"{name}_leaf{i}", leaf[i % 2], p, _u(rng, *size)))
    return out


def plant(rng, mats: MaterialPicker, name: str) -> Item:
    """A pot plant for a table or shelf top."""
    r, ph = _u(rng, 0.05, 0.08), _u(rng, 0.08, 0.13)
    pot = mats.pick(str(rng.choice(["ceramic", "ceramic", "plastic"])))
    spread = r * 1.3
    shapes = [cylinder(f"{name}_pot", pot, (0, 0, 0), (0, ph, 0), r),
              disk(f"{name}_soil", mats.pick("soil"), (0, ph - 0.01, 0), (0, 1, 0), r)]
    shapes += _foliage(rng, mats, name, (0, ph + spread, 0), spread, int(rng.integers(5, 10)), (0.025, 0.045))
    w = 2 * (spread + 0.045)
    return Item("plant", shapes, (w, w), ph + 2 * spread + 0.1)


def floor_plant(rng, mats: MaterialPicker, name: str) -> Item:
    """A large plant in a floor pot: trunk and canopy."""
    r, ph, th = _u(rng, 0.15, 0.22), _u(rng, 0.25, 0.4), _u(rng, 0.5, 1.0)
    pot = mats.pick(str(rng.choice(["ceramic", "plastic", "wood"])))
    spread = _u(rng, 0.25, 0.35)
    shapes = [cylinder(f"{name}_pot", pot, (0, 0, 0), (0, ph, 0), r),
              disk(f"{name}_soil", mats.pick("soil"), (0, ph - 0.02, 0), (0, 1, 0), r),
              cylinder(f"{name}_trunk", mats.pick("wood"), (0, ph - 0.02, 0), (0, ph + th, 0), 0.02)]
    shapes += _foliage(rng, mats, name, (0, ph + th, 0), spread, int(rng.integers(8, 14)), (0.07, 0.12))
    w = 2 * (spread + 0.12)
    return Item("floor_plant", shapes, (w, w), ph + th + spread + 0.12)


def vase(rng, mats: MaterialPicker, name: str) -> Item:
    """A vase, often with a few flowers."""
    r, h = _u(rng, 0.04, 0.07), _u(rng, 0.15, 0.3)
    m = mats.pick(str(rng.choice(["ceramic", "glass"])))
    shapes = [cylinder(f"{name}_body", m, (0, 0, 0), (0, h, 0), r),
              disk(f"{name}_base", m, (0, 0.004, 0), (0, 1, 0), r)]
    if rng.random() < 0.6:
        petals = mats.pick("food") if rng.random() < 0.5 else mats.pick("accent")
        for i in range(int(rng.integers(2, 5))):
            a = 2 * math.pi * i / 4 + float(rng.uniform(-0.3, 0.3))
            top = (0.6 * r * math.cos(a), h + float(rng.uniform(0.08, 0.18)), 0.6 * r * math.sin(a))
            shapes.append(cylinder(f"{name}_stem{i}", mats.pick("plant"), (0, h - 0.05, 0), top, 0.003))
            shapes.append(sphere(f"{name}_flower{i}", petals, top, 0.02))
    return Item("vase", shapes, (2 * r + 0.04, 2 * r + 0.04), h + 0.22)


def book_stack(rng, mats: MaterialPicker, name: str) -> Item:
    bw, bd = _u(rng, 0.14, 0.22), _u(rng, 0.2, 0.28)
    shapes, y = [], 0.0
    for i in range(int(rng.integers(1, 5))):
        t = _u(rng, 0.015, 0.045)
        dx, dz = float(rng.uniform(-0.01, 0.01)), float(rng.uniform(-0.01, 0.01))
        shapes.append(box(f"{name}_book{i}", mats.pick("book"), (dx, y + t / 2, dz), (bw / 2, t / 2, bd / 2)))
        y += t
    return Item("book_stack", shapes, (bw + 0.02, bd + 0.02), y)


def storage_box(rng, mats: MaterialPicker, name: str) -> Item:
    w, d, h = _u(rng, 0.15, 0.35), _u(rng, 0.12, 0.3), _u(rng, 0.08, 0.25)
    m = mats.pick(str(rng.choice(["paper", "wood", "plastic", "fabric"])))
    return Item("box", [box(f"{name}_box", m, (0, h / 2, 0), (w / 2, h / 2, d / 2))], (w, d), h)


def frame(rng, mats: MaterialPicker, name: str) -> Item:
    """A framed picture for a wall: frame, mount and a picture texture (spectral label map)."""
    w, h = _u(rng, 0.3, 1.0), _u(rng, 0.3, 0.8)
    border, depth = _u(rng, 0.02, 0.05), 0.025
    fm = mats.pick(str(rng.choice(["wood", "black", "metal", "white"])))
    shapes = [box(f"{name}_frame", fm, (0, h / 2, 0), (w / 2, h / 2, depth / 2)),
              rect(f"{name}_picture", mats.pick("picture"), (0, h / 2, depth / 2 + 0.001), (0, 0, 1), (0, 1, 0),
                   (w - 2 * border, h - 2 * border))]
    return Item("frame", shapes, (w, depth), h, against_wall=True)


def clock(rng, mats: MaterialPicker, name: str) -> Item:
    r = _u(rng, 0.12, 0.2)
    rim = mats.pick(str(rng.choice(["metal", "black", "wood", "plastic"])))
    shapes = [cylinder(f"{name}_rim", rim, (0, r, -0.02), (0, r, 0.02), r),
              disk(f"{name}_face", mats.pick("paper"), (0, r, 0.015), (0, 0, 1), r - 0.01),
              box(f"{name}_hand0", mats.pick("black"), (0, r + r * 0.3, 0.018), (0.004, r * 0.3, 0.002)),
              box(f"{name}_hand1", mats.pick("black"), (r * 0.25, r, 0.019), (r * 0.25, 0.004, 0.002))]
    return Item("clock", shapes, (2 * r, 0.04), 2 * r, against_wall=True)


def rug(rng, mats: MaterialPicker, name: str) -> Item:
    """A rug (a thin slab with a woven / striped / patterned spectral texture); furniture may stand on it."""
    w, d = _u(rng, 1.2, 2.5), _u(rng, 0.8, 1.8)
    return Item("rug", [box(f"{name}_rug", mats.pick("rug"), (0, 0.004, 0), (w / 2, 0.004, d / 2))], (w, d), 0.008)


TABLETOP = {"mug": mug, "bottle": bottle, "bowl": bowl, "plant": plant, "vase": vase,
            "book_stack": book_stack, "box": storage_box}
WALL = {"frame": frame, "clock": clock}
FLOOR = {"rug": rug, "floor_plant": floor_plant}
