"""Appliances, beds, kitchen runs and doors as triangle meshes: a fridge-freezer, a free-standing
cooker (oven door with a window, knobs, hob rings), a washing machine (porthole door, dial, soap
drawer), beds with a padded headboard, mattress, duvet and pillows, kitchen counters with framed unit
doors, a sink and a tap, and closed doors in their frames with a lever handle.

Builders are ``(rng, mats, name) -> Item`` (:mod:`scenegen.parts`: item frame, front ``+z``); all
stand with their back to a wall. A door is hung by :meth:`scenegen.placement.Placer.door`.
"""

from __future__ import annotations

import math

from illumix.scenegen import mesh as M
from illumix.scenegen.meshfurniture import _knob, shaker_door
from illumix.scenegen.meshparts import Parts
from illumix.scenegen.parts import Item, MaterialPicker, Surface


def _u(rng, lo: float, hi: float) -> float:
    return round(float(rng.uniform(lo, hi)), 4)


def _enamel(rng, mats: MaterialPicker) -> str:
    return mats.pick(str(rng.choice(["white", "white", "metal", "plastic"])))


def _bar(p: Parts, mat: str, a, b, stand: float = 0.035) -> None:
    """A bar handle from ``a`` to ``b`` (on a front facing +z), on two short posts."""
    p.add(mat, M.rod((a[0], a[1], a[2] + stand), (b[0], b[1], b[2] + stand), 0.009, 10))
    for q in (a, b):
        p.add(mat, M.rod(q, (q[0], q[1], q[2] + stand), 0.007, 8))


def fridge(rng, mats: MaterialPicker, name: str) -> Item:
    """A fridge-freezer: a rounded cabinet, freezer door below and fridge door above, bar handles."""
    w, d, h = _u(rng, 0.55, 0.7), _u(rng, 0.6, 0.68), _u(rng, 1.7, 1.9)
    body, handle, p = _enamel(rng, mats), mats.pick(str(rng.choice(["metal", "black", "plastic"]))), Parts(name)
    p.add(body, M.rounded_box((w / 2, h / 2 - 0.02, d / 2 - 0.04), 0.02).at(0, h / 2 + 0.01, -0.04))
    p.add(mats.pick("black"), M.box((0, 0.015, -0.02), (w / 2 - 0.03, 0.015, d / 2 - 0.06)))
    split = h * _u(rng, 0.38, 0.45)
    zf = d / 2 - 0.04
    for y0, y1 in ((0.03, split - 0.004), (split + 0.004, h)):
        p.add(body, M.rounded_box((w / 2 - 0.002, (y1 - y0) / 2, 0.025), 0.012).at(0, (y0 + y1) / 2, zf + 0.025))
    hx = w / 2 - 0.06
    _bar(p, handle, (hx, split - 0.3, zf + 0.05), (hx, split - 0.05, zf + 0.05))
    _bar(p, handle, (hx, split + 0.08, zf + 0.05), (hx, split + 0.5, zf + 0.05))
    return Item("fridge", p.shapes(), (w, d + 0.06), h, against_wall=True)


def oven(rng, mats: MaterialPicker, name: str) -> Item:
    """A free-standing cooker: body, oven door with a dark window and a bar handle, a control strip
    with knobs, a hob with four burner rings on top."""
    w, d, h = float(rng.choice([0.5, 0.6])), 0.6, _u(rng, 0.86, 0.92)
    body, dark, metal, p = _enamel(rng, mats), mats.pick("black"), mats.pick("metal"), Parts(name)
    p.add(body, M.bevel_box((0, h / 2, -0.02), (w / 2, h / 2, d / 2 - 0.02), 0.006))
    zf = d / 2 - 0.04
    p.add(body, M.bevel_box((0, 0.42, zf + 0.015), (w / 2 - 0.01, 0.3, 0.015), 0.005))
    p.add(dark, M.box((0, 0.44, zf + 0.031), (w / 2 - 0.08, 0.16, 0.002)))
    _bar(p, metal, (-w / 2 + 0.07, 0.68, zf + 0.03), (w / 2 - 0.07, 0.68, zf + 0.03))
    p.add(dark, M.box((0, 0.06, zf), (w / 2 - 0.02, 0.05, 0.012)))
    for i in range(4):
        _knob(p, dark, -w / 2 + w * (i + 0.5) / 4, h - 0.07, zf + 0.02)
    p.add(dark, M.box((0, h + 0.003, -0.02), (w / 2 - 0.005, 0.003, d / 2 - 0.025)), apart="hob")
    ring = [(0.04, 0.0), (0.075, 0.0), (0.075, 0.012), (0.04, 0.012), (0.04, 0.0)]
    for sx, sz, s in ((-1, -1, 1.0), (1, -1, 0.8), (-1, 1, 0.8), (1, 1, 1.0)):
        prof = [(r * s, y) for r, y in ring]
        p.add(metal, M.lathe(prof, 20).at(sx * w / 4, h + 0.006, -0.02 + sz * 0.13))
    return Item("oven", p.shapes(), (w, d), h + 0.02, against_wall=True)


def washing_machine(rng, mats: MaterialPicker, name: str) -> Item:
    """A front-loading washing machine: body, a porthole door (chrome ring round a dark glass), a control
    panel with a dial and a soap drawer; its top carries clutter."""
    w, d, h = 0.6, _u(rng, 0.55, 0.62), 0.85
    body, metal, dark, p = _enamel(rng, mats), mats.pick("metal"), mats.pick("black"), Parts(name)
    p.add(body, M.rounded_box((w / 2, h / 2, d / 2 - 0.01), 0.015).at(0, h / 2, -0.01))
    zf = d / 2 - 0.02
    ring = [(0.14, 0.0), (0.2, 0.0), (0.2, 0.03), (0.16, 0.04), (0.14, 0.03), (0.14, 0.0)]
    p.add(metal, M.lathe(ring, 40).moved(M.rotate_x(math.pi / 2)).at(0, 0.4, zf))
    p.add(dark, M.lathe([(0, 0), (0.141, 0), (0.141, 0.02), (0.08, 0.035), (0, 0.04)], 40, sharp=(1, 2))
          .moved(M.rotate_x(math.pi / 2)).at(0, 0.4, zf))
    p.add(body, M.bevel_box((-w / 2 + 0.11, h - 0.07, zf + 0.006), (0.09, 0.04, 0.008), 0.003))
    p.add(metal, M.lathe([(0, 0), (0.03, 0), (0.028, 0.025), (0, 0.027)], 24, sharp=(1,))
          .moved(M.rotate_x(math.pi / 2)).at(w / 2 - 0.1, h - 0.07, zf))
    return Item("washing_machine", p.shapes(), (w, d + 0.05), h, [Surface(h, (0, -0.01), (w - 0.02, d - 0.04))],
                against_wall=True)


def bed(rng, mats: MaterialPicker, name: str) -> Item:
    """A bed with its head to a wall: frame on legs, padded headboard, mattress, duvet, pillows."""
    w = float(rng.choice([0.9, 1.2, 1.4, 1.6, 1.8]))
    d, fh, mh = _u(rng, 2.0, 2.15), _u(rng, 0.25, 0.35), _u(rng, 0.18, 0.25)
    frame = mats.pick(str(rng.choice(["wood", "wood", "paint", "fabric"])))
    linen, duvet = mats.pick("linen"), mats.pick(str(rng.choice(["linen", "fabric"])))
    top, hb, p = fh + mh, _u(rng, 0.9, 1.2), Parts(name)
    p.add(frame, M.bevel_box((0, fh * 0.6, 0.03), (w / 2, fh * 0.4, d / 2 - 0.03), 0.01))
    for sx, sz in ((-1, -1), (1, -1), (-1, 1), (1, 1)):
        p.add(frame, M.box((sx * (w / 2 - 0.05), fh * 0.1, sz * (d / 2 - 0.08) + 0.03), (0.03, fh * 0.1, 0.03)))
    p.add(frame, M.rounded_box((w / 2, hb / 2, 0.04), 0.03, 3).at(0, hb / 2, -d / 2 + 0.04))
    p.add(linen, M.rounded_box((w / 2 - 0.03, mh / 2, d / 2 - 0.07), 0.04, 3).at(0, fh + mh / 2, 0.04))
    p.add(duvet, M.rounded_box((w / 2 + 0.02, 0.04, d / 2 - 0.32), 0.035, 3, bulge=0.015).at(0, top + 0.02, 0.3))
    n = 1 if w < 1.3 else 2
    for i in range(n):
        x = -w / 2 + w * (i + 0.5) / n
        pil = M.rounded_box((w / n / 2 - 0.08, 0.045, 0.17), 0.045, 3, bulge=0.02).moved(M.rotate_x(-0.25))
        p.add(linen, pil.at(x, top + 0.09, -d / 2 + 0.3))
    return Item("bed", p.shapes(), (w + 0.04, d), hb, against_wall=True)


def kitchen_counter(rng, mats: MaterialPicker, name: str) -> Item:
    """A run of base units with framed doors and knobs, a worktop, an inset sink with a tap and often
    a hob."""
    w, d, h = _u(rng, 1.5, 3.0), 0.62, _u(rng, 0.86, 0.92)
    units = mats.pick(str(rng.choice(["paint", "plastic", "wood", "accent"])))
    top, metal = mats.pick(str(rng.choice(["tile", "wood", "ceramic", "black"]))), mats.pick("metal")
    t, plinth, p = 0.04, 0.1, Parts(name)
    p.add(mats.pick("black"), M.box((0, plinth / 2, -0.03), (w / 2, plinth / 2, d / 2 - 0.07)))
    p.add(units, M.box((0, (plinth + h - t) / 2, -0.02), (w / 2, (h - t - plinth) / 2, d / 2 - 0.04)))
    p.add(top, M.bevel_box((0, h - t / 2, 0), (w / 2, t / 2, d / 2), 0.004))
    doors = max(2, round(w / 0.6))
    for i in range(doors):
        x = -w / 2 + w * (i + 0.5) / doors
        shaker_door(p, units, x, (plinth + h - t) / 2, w / doors - 0.006, h - t - plinth - 0.01, d / 2 - 0.02)
        _knob(p, metal, x + (w / doors / 2 - 0.05) * (1 if i % 2 else -1), h - t - 0.09, d / 2 + 0.006)
    sx = _u(rng, -w / 2 + 0.4, w / 2 - 0.4)
    rim = [(0.0, 0.0), (0.03, 0.0), (0.03, 0.004), (0.0, 0.004)]
    p.add(metal, M.frame_ring(0.44, 0.36, rim).moved(M.rotate_x(-math.pi / 2)).at(sx, h, 0.02), apart="sink")
    p.add(metal, M.box((sx, h - 0.15, 0.02), (0.22, 0.004, 0.18)), apart="sink")
    p.add(metal, M.rod((sx, h, -0.22), (sx, h + 0.28, -0.22), 0.014, 12), apart="sink")
    p.add(metal, M.rod((sx, h + 0.27, -0.22), (sx, h + 0.27, -0.05), 0.011, 12), apart="sink")
    busy = [(sx - 0.3, sx + 0.3)]
    if w > 1.9:
        hx = (w / 2 - 0.35) * (-1.0 if sx > 0 else 1.0)
        p.add(mats.pick("black"), M.bevel_box((hx, h + 0.003, 0.0), (0.29, 0.003, 0.25), 0.002), apart="hob")
        busy.append((hx - 0.32, hx + 0.32))
    a, b = max(_free_spans((-w / 2 + 0.02, w / 2 - 0.02), busy), key=lambda s: s[1] - s[0])
    surfaces = [Surface(h, ((a + b) / 2, 0.02), (b - a, d - 0.08))] if b - a > 0.2 else []
    return Item("kitchen_counter", p.shapes(), (w, d), h + 0.3, surfaces, against_wall=True)


def wall_cabinet(rng, mats: MaterialPicker, name: str, width: float, height: float) -> Item:
    """A run of kitchen wall units ``width`` wide, ``height`` high, 33 cm deep: carcass, framed doors
    with knobs near their bottom edge; hung with its back to the wall (front +z)."""
    units = mats.pick(str(rng.choice(["paint", "plastic", "wood", "accent", "white"])))
    knob, d, p = mats.pick(str(rng.choice(["metal", "black"]))), 0.33, Parts(name)
    p.add(units, M.bevel_box((0, height / 2, -0.012), (width / 2, height / 2, d / 2 - 0.012), 0.003))
    doors = max(1, round(width / 0.5))
    for i in range(doors):
        x = -width / 2 + width * (i + 0.5) / doors
        shaker_door(p, units, x, height / 2, width / doors - 0.006, height - 0.006, d / 2 - 0.024)
        _knob(p, knob, x + (width / doors / 2 - 0.05) * (1 if i % 2 else -1), 0.08, d / 2 + 0.002)
    return Item("wall_cabinet", p.shapes(), (width, d + 0.04), height, against_wall=True)


def _free_spans(span: tuple[float, float], busy: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The parts of ``span`` not covered by any interval in ``busy``."""
    out, x = [], span[0]
    for a, b in sorted(busy):
        if a > x:
            out.append((x, min(a, span[1])))
        x = max(x, b)
    if x < span[1]:
        out.append((x, span[1]))
    return out or [(0.0, 0.0)]


def door(rng, mats: MaterialPicker, name: str) -> Item:
    """A closed door (0.8–0.9 × 2.0–2.1 m) in a moulded frame with a lever handle; stands on the floor
    flat against a wall (front +z)."""
    w, h = float(rng.choice([0.8, 0.85, 0.9])), _u(rng, 2.0, 2.1)
    leafm = mats.pick(str(rng.choice(["wood", "paint", "white"])))
    framem = leafm if rng.random() < 0.5 else mats.pick(str(rng.choice(["paint", "white", "wood"])))
    metal, p = mats.pick(str(rng.choice(["metal", "black"]))), Parts(name)
    sec = [(0.0, 0.0), (0.07, 0.0), (0.07, 0.012), (0.06, 0.02), (0.0, 0.024)]
    p.add(framem, M.frame_ring(w, h + 0.05, sec).at(0, (h - 0.05) / 2, -0.04))
    p.add(leafm, M.box((0, h / 2, -0.03), (w / 2, h / 2, 0.008)))
    panels = int(rng.integers(1, 4))
    for k in range(panels):
        ph = (h - 0.3) / panels
        shaker_door(p, leafm, 0.0, 0.15 + ph * (k + 0.5), w - 0.16, ph - 0.1, -0.022)
    hx = w / 2 - 0.07
    p.add(metal, M.rod((hx, 1.0, -0.01), (hx, 1.0, 0.045), 0.009, 10))
    p.add(metal, M.rod((hx, 1.0, 0.045), (hx - 0.12, 1.0, 0.045), 0.009, 10))
    p.add(metal, M.bevel_box((hx, 1.0, -0.005), (0.018, 0.06, 0.005), 0.002))
    return Item("door", p.shapes(), (w + 0.14, 0.08), h + 0.05, against_wall=True)
