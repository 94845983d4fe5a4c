"""Furniture as triangle meshes with real detail: chairs (tapered or turned legs, stretchers, aprons,
slatted / ladder / upholstered backs), tables (aprons, tapered or turned legs; round ones on a turned
pedestal), sofas (plinth, puffed seat and back cushions, rolled arms, throw pillows), desks with
drawer pedestals, cabinets with framed (Shaker) doors, drawers and knobs, and bookcases filled with
books of varied height, thickness and depth, some in flat stacks.

Builders are ``(rng, mats, name) -> Item`` in the item's frame (:mod:`scenegen.parts`: origin at the
centre of the footprint on the floor, front ``+z``); each returns one ``ply`` shape per material
(:class:`scenegen.meshparts.Parts`). Sizes are those of ordinary furniture (m).
"""

from __future__ import annotations

import math

import numpy as np

from illumix.scenegen import mesh as M
from illumix.scenegen.meshparts import Parts
from illumix.scenegen.parts import Item, MaterialPicker, Surface


def _u(rng, lo: float, hi: float) -> float:
    return round(float(rng.uniform(lo, hi)), 4)


def leg(style: str, h: float, t: float) -> M.Mesh:
    """A leg of height ``h``, thickness ``t`` at the top, standing on y = 0: ``square`` tapered,
    ``round`` tapered, or ``turned`` (a lathe profile with a bead and a foot)."""
    if style == "square":
        m = M.lathe([(0, 0), (0.5 * t * 0.72 * math.sqrt(2), 0), (0.5 * t * math.sqrt(2), h), (0, h)], 4, sharp=(1, 2))
        return m.moved(M.rotate_y(math.pi / 4))
    if style == "round":
        return M.lathe([(0, 0), (0.36 * t, 0), (0.5 * t, h), (0, h)], 14, sharp=(1, 2))
    r = t / 2
    prof = [(0, 0), (0.6 * r, 0), (0.75 * r, 0.03), (0.55 * r, 0.07), (0.6 * r, 0.45 * h), (0.95 * r, 0.5 * h),
            (0.6 * r, 0.55 * h), (0.8 * r, 0.85 * h), (r, 0.88 * h), (r, h), (0, h)]
    return M.lathe(prof, 14, sharp=(1, 9))


def _four_legs(p: Parts, mat: str, style: str, w: float, d: float, h: float, t: float, inset: float) -> None:
    for sx, sz in ((-1, -1), (1, -1), (-1, 1), (1, 1)):
        p.add(mat, leg(style, h, t).at(sx * (w / 2 - inset - t / 2), 0, sz * (d / 2 - inset - t / 2)))


def _apron(p: Parts, mat: str, w: float, d: float, y: float, depth: float, t: float, inset: float) -> None:
    """Rails under a top: ``depth`` high, ``t`` thick, their top at ``y``, ``inset`` from the edges."""
    for sz in (-1, 1):
        p.add(mat, M.box((0, y - depth / 2, sz * (d / 2 - inset - t / 2)), (w / 2 - inset - t, depth / 2, t / 2)))
    for sx in (-1, 1):
        p.add(mat, M.box((sx * (w / 2 - inset - t / 2), y - depth / 2, 0), (t / 2, depth / 2, d / 2 - inset - t)))


def chair(rng, mats: MaterialPicker, name: str) -> Item:
    """A dining chair: legs, side stretchers, apron, a seat (board or upholstered pad) and a back
    (vertical slats, horizontal ladder rails or an upholstered panel) between two rear posts."""
    w, d, sh, bh = _u(rng, 0.42, 0.5), _u(rng, 0.42, 0.5), _u(rng, 0.43, 0.48), _u(rng, 0.38, 0.5)
    frame = mats.pick(str(rng.choice(["wood", "wood", "wood", "metal", "plastic", "black"])))
    pad = mats.pick(str(rng.choice(["fabric", "leather"]))) if rng.random() < 0.5 else None
    style = str(rng.choice(["square", "round", "turned"] if frame.startswith("wood") else ["square", "round"]))
    t, p = 0.036, Parts(name)
    seat_t = 0.025
    _four_legs(p, frame, style, w, d, sh - seat_t, t, 0.012)
    _apron(p, frame, w, d, sh - seat_t, 0.06, 0.018, 0.02)
    for sx in (-1, 1):  # side stretchers
        x = sx * (w / 2 - 0.012 - t / 2)
        p.add(frame, M.rod((x, 0.14, -d / 2 + 0.03), (x, 0.14, d / 2 - 0.03), 0.009, 8))
    p.add(frame, M.bevel_box((0, sh - seat_t / 2, 0), (w / 2, seat_t / 2, d / 2), 0.005))
    if pad:
        p.add(pad, M.rounded_box((w / 2 - 0.02, 0.02, d / 2 - 0.02), 0.018, 3, bulge=0.008).at(0, sh + 0.02, 0.005))
    zb = -d / 2 + 0.012 + t / 2
    for sx in (-1, 1):  # rear posts, leaning back a little
        x = sx * (w / 2 - 0.012 - t / 2)
        p.add(frame, M.rod((x, sh - 0.01, zb), (x, sh + bh, zb - 0.04), t / 2 * 0.9, 10))
    inner = w - 2 * (0.012 + t)
    back = str(rng.choice(["slats", "ladder", "panel"]))
    def lean(y: float) -> float:  # the back posts lean 4 cm back over the back's height
        return zb - 0.04 * (y - sh) / bh

    p.add(frame, M.bevel_box((0, sh + bh - 0.04, lean(sh + bh - 0.04)), (inner / 2 + 0.005, 0.035, 0.011), 0.004))
    if back == "slats":
        n = int(rng.integers(3, 6))
        y0, y1 = sh + 0.08, sh + bh - 0.075
        p.add(frame, M.box((0, y0, lean(y0)), (inner / 2 + 0.005, 0.015, 0.01)))
        for i in range(n):
            x = -inner / 2 + inner * (i + 0.5) / n
            p.add(frame, M.box((x, (y0 + y1) / 2, lean((y0 + y1) / 2)), (inner / n * 0.3, (y1 - y0) / 2, 0.007)))
    elif back == "ladder":
        for k in range(int(rng.integers(2, 4))):
            y = sh + 0.12 + k * 0.1
            if y < sh + bh - 0.1:
                p.add(frame, M.bevel_box((0, y, lean(y)), (inner / 2 + 0.005, 0.022, 0.009), 0.003))
    else:
        y = sh + bh * 0.55
        p.add(pad or frame, M.rounded_box((inner / 2, bh * 0.28, 0.018), 0.012, 2, bulge=0.0).at(0, y, lean(y) + 0.012))
    return Item("chair", p.shapes(), (w, d + 0.04), sh + bh)


def table(rng, mats: MaterialPicker, name: str) -> Item:
    """A dining table: a bevelled top on an apron and four legs, or a round top on a turned pedestal."""
    h, t = _u(rng, 0.72, 0.77), _u(rng, 0.025, 0.045)
    top = mats.pick(str(rng.choice(["wood", "wood", "plastic", "tile"])))
    p = Parts(name)
    if rng.random() < 0.3:
        r = _u(rng, 0.45, 0.65)
        base = mats.pick(str(rng.choice(["metal", "wood", "black"])))
        p.add(top, M.lathe([(0, h - t), (r - 0.008, h - t), (r, h - t / 2), (r - 0.008, h), (0, h)], 48, sharp=(1, 3)))
        col = [(0, 0), (0.26, 0), (0.26, 0.02), (0.12, 0.05), (0.05, 0.1), (0.04, 0.4), (0.06, h - t - 0.08),
               (0.1, h - t - 0.02), (0.1, h - t), (0, h - t)]
        p.add(base, M.lathe(col, 24, sharp=(1, 2, 8)))
        side = r * 2 ** 0.5
        return Item("table", p.shapes(), (2 * r, 2 * r), h, [Surface(h, (0, 0), (side, side))])
    w = _u(rng, 0.9, 1.9)
    d = _u(rng, 0.7, min(1.0, w))
    legm = mats.pick(str(rng.choice(["wood", "metal", "black"]))) if rng.random() < 0.5 else top
    p.add(top, M.bevel_box((0, h - t / 2, 0), (w / 2, t / 2, d / 2), 0.006))
    lt = _u(rng, 0.045, 0.07)
    _four_legs(p, legm, str(rng.choice(["square", "round", "turned"])), w, d, h - t, lt, 0.05)
    _apron(p, legm, w, d, h - t, 0.09, 0.02, 0.05 + lt / 2 - 0.01)
    return Item("table", p.shapes(), (w, d), h, [Surface(h, (0, 0), (w, d))])


def coffee_table(rng, mats: MaterialPicker, name: str) -> Item:
    """A low table for in front of a sofa: a bevelled top, a shelf below, four square or round legs."""
    w, d, h = _u(rng, 0.8, 1.2), _u(rng, 0.45, 0.65), _u(rng, 0.38, 0.46)
    top = mats.pick(str(rng.choice(["wood", "wood", "glass", "paint", "black"])))
    frame = top if not top.startswith("glass") else mats.pick(str(rng.choice(["metal", "black", "wood"])))
    p = Parts(name)
    p.add(top, M.bevel_box((0, h - 0.015, 0), (w / 2, 0.015, d / 2), 0.004))
    _four_legs(p, frame, str(rng.choice(["square", "round"])), w, d, h - 0.03, 0.045, 0.03)
    p.add(frame, M.box((0, 0.12, 0), (w / 2 - 0.075, 0.01, d / 2 - 0.075)))
    return Item("coffee_table", p.shapes(), (w, d), h, [Surface(h, (0, 0), (w, d))])


def sofa(rng, mats: MaterialPicker, name: str) -> Item:
    """A sofa against a wall: plinth on short legs, puffed seat and back cushions, rolled arms and
    0–2 throw pillows."""
    seats, arm = int(rng.integers(2, 4)), _u(rng, 0.14, 0.24)
    w, d = seats * _u(rng, 0.55, 0.7) + 2 * arm, _u(rng, 0.85, 1.0)
    sh, h = _u(rng, 0.4, 0.46), _u(rng, 0.75, 0.9)
    cover = mats.pick(str(rng.choice(["fabric", "fabric", "leather"])))
    cushion = cover if rng.random() < 0.7 else mats.pick("fabric")
    legs, p = mats.pick(str(rng.choice(["wood", "metal", "black"]))), Parts(name)
    base_y, back_d, inner = 0.1, 0.2, w - 2 * arm
    _four_legs(p, legs, "round", w - 0.06, d - 0.06, base_y, 0.045, 0.0)
    p.add(cover, M.rounded_box((w / 2, (sh - 0.12 - base_y) / 2, d / 2), 0.02).at(0, (base_y + sh - 0.12) / 2, 0))
    p.add(cover, M.rounded_box((inner / 2, (h - 0.1 - base_y) / 2, 0.06), 0.02).at(0, (h - 0.1 + base_y) / 2, -d / 2 + 0.06))
    for i in range(seats):
        x = -inner / 2 + inner * (i + 0.5) / seats
        cw = inner / seats / 2 - 0.004
        p.add(cushion, M.rounded_box((cw, 0.055, (d - back_d) / 2 - 0.004), 0.04, 3, bulge=0.012).at(x, sh - 0.065, back_d / 2))
        back = M.rounded_box((cw, (h - sh) / 2 - 0.01, back_d / 2 - 0.03), 0.05, 3, bulge=0.0)
        p.add(cushion, back.moved(M.rotate_x(-0.17)).at(x, (sh + h) / 2, -d / 2 + 0.12 + back_d / 2 - 0.03))
    ah = sh + 0.2
    prof = [(-arm / 2, base_y), (arm / 2, base_y)] + [
        (arm / 2 * math.cos(a), ah - arm / 2 + arm / 2 * 0.9 * math.sin(a)) for a in np.linspace(0, math.pi, 10)]
    for sx in (-1, 1):
        p.add(cover, M.extrude(prof, -d / 2, d / 2, smooth_sides=True).at(sx * (w / 2 - arm / 2), 0, 0))
    for i in range(int(rng.integers(0, 3))):
        pil = mats.pick(str(rng.choice(["fabric", "linen", "accent"])))
        x = (-1) ** i * (inner / 2 - 0.25)
        pm = M.rounded_box((0.2, 0.2, 0.06), 0.05, 3).moved(M.rotate_x(-0.3)).moved(M.rotate_y((-1) ** i * 0.25))
        p.add(pil, pm.at(x, sh + 0.2, -d / 2 + back_d + 0.06), uv="unit")
    return Item("sofa", p.shapes(), (w, d), h, against_wall=True)


def desk(rng, mats: MaterialPicker, name: str) -> Item:
    """A desk against a wall: a top on side panels or legs, a modesty panel, often a drawer pedestal."""
    w, d, h, t = _u(rng, 1.0, 1.6), _u(rng, 0.55, 0.75), _u(rng, 0.72, 0.76), 0.028
    top = mats.pick(str(rng.choice(["wood", "plastic", "paint"])))
    p = Parts(name)
    p.add(top, M.bevel_box((0, h - t / 2, 0), (w / 2, t / 2, d / 2), 0.004))
    if rng.random() < 0.5:
        for sx in (-1, 1):
            p.add(top, M.bevel_box((sx * (w / 2 - 0.015), (h - t) / 2, 0), (0.015, (h - t) / 2, d / 2 - 0.01), 0.003))
        p.add(top, M.box((0, h - t - 0.2, -d / 2 + 0.05), (w / 2 - 0.03, 0.17, 0.008)))
    else:
        _four_legs(p, mats.pick(str(rng.choice(["metal", "black"]))), "round", w, d, h - t, 0.04, 0.03)
    if rng.random() < 0.6:
        pw, sx = 0.4, float(rng.choice([-1, 1]))
        x = sx * (w / 2 - 0.05 - pw / 2)
        _drawers(p, mats, x, 0.0, h - t, pw, d - 0.08, 3, -0.02)
    return Item("desk", p.shapes(), (w, d), h, [Surface(h, (0, 0), (w, d))], against_wall=True)


def _drawers(p: Parts, mats: MaterialPicker, x: float, y0: float, y1: float, w: float, d: float, n: int,
             z: float) -> None:
    """A pedestal of ``n`` drawers with bar handles between heights ``y0`` and ``y1`` (front at +z)."""
    body = mats.pick(str(rng_free_choice(mats, ["paint", "plastic", "wood"])))
    handle = mats.pick("metal")
    p.add(body, M.box((x, (y0 + y1) / 2, z - 0.01), (w / 2, (y1 - y0) / 2 - 0.002, d / 2 - 0.01)))
    for k in range(n):
        a, b = y0 + (y1 - y0) * k / n, y0 + (y1 - y0) * (k + 1) / n
        p.add(body, M.bevel_box((x, (a + b) / 2, z + d / 2 - 0.008), (w / 2 - 0.004, (b - a) / 2 - 0.004, 0.009), 0.003))
        yh, zh = (a + b) / 2 + (b - a) * 0.2, z + d / 2 + 0.001
        p.add(handle, M.rod((x - 0.06, yh, zh + 0.025), (x + 0.06, yh, zh + 0.025), 0.006, 8))
        for sx in (-1, 1):
            p.add(handle, M.rod((x + sx * 0.05, yh, zh), (x + sx * 0.05, yh, zh + 0.025), 0.005, 8))


def rng_free_choice(mats: MaterialPicker, classes: list[str]) -> str:
    """A class for a part when no generator is at hand: the picker's own generator decides."""
    rng = getattr(mats, "rng", None)
    return classes[int(rng.integers(len(classes)))] if rng is not None else classes[0]


def shaker_door(p: Parts, mat: str, x: float, y: float, w: float, h: float, z: float) -> None:
    """A framed door front ``w × h`` centred at ``(x, y)``, its back at ``z``: a flat panel and a
    bevelled frame around it."""
    p.add(mat, M.box((x, y, z + 0.006), (w / 2, h / 2, 0.006)))
    rail = min(0.07, w / 5, h / 5)
    sec = [(0, 0.012), (rail - 0.004, 0.012), (rail, 0.008), (rail, 0.022), (rail - 0.004, 0.026), (0.004, 0.026),
           (0, 0.02)]
    p.add(mat, M.frame_ring(w - 2 * rail, h - 2 * rail, sec).at(x, y, z))


def cabinet(rng, mats: MaterialPicker, name: str) -> Item:
    """A sideboard or chest against a wall: plinth, carcass, overhanging top, framed doors (or a row of
    drawers on top) with knobs or bar handles; its top carries clutter."""
    w, d, h = _u(rng, 0.6, 1.8), _u(rng, 0.38, 0.55), _u(rng, 0.6, 1.3)
    body = mats.pick(str(rng.choice(["wood", "paint", "plastic"])))
    front = body if rng.random() < 0.6 else mats.pick(str(rng.choice(["paint", "wood", "accent"])))
    handle = mats.pick(str(rng.choice(["metal", "black"])))
    plinth, p = 0.08, Parts(name)
    p.add(mats.pick("black"), M.box((0, plinth / 2, 0.0), (w / 2 - 0.03, plinth / 2, d / 2 - 0.05)))
    p.add(body, M.bevel_box((0, (plinth + h - 0.025) / 2, -0.015), (w / 2, (h - 0.025 - plinth) / 2, d / 2 - 0.015), 0.002))
    p.add(body, M.bevel_box((0, h - 0.0125, 0.005), (w / 2 + 0.01, 0.0125, d / 2 + 0.005), 0.004))
    doors = max(1, round(w / 0.45))
    top_drawers = h > 0.8 and rng.random() < 0.5
    y1 = h - 0.03 - (0.16 if top_drawers else 0.0)
    zf = d / 2 - 0.015
    for i in range(doors):
        x = -w / 2 + w * (i + 0.5) / doors
        dw = w / doors - 0.006
        shaker_door(p, front, x, (plinth + y1) / 2, dw, y1 - plinth - 0.006, zf)
        hx = x + (dw / 2 - 0.05) * (1 if i % 2 == 0 else -1)
        _knob(p, handle, hx, y1 - 0.1, zf + 0.026)
        if top_drawers:
            p.add(front, M.bevel_box((x, h - 0.03 - 0.08, zf + 0.012), (dw / 2, 0.075, 0.012), 0.003))
            _knob(p, handle, x, h - 0.11, zf + 0.024)
    return Item("cabinet", p.shapes(), (w + 0.02, d + 0.06), h, [Surface(h, (0, 0.005), (w, d))], against_wall=True)


def _knob(p: Parts, mat: str, x: float, y: float, z: float) -> None:
    """A turned knob on a door front at ``z``, pointing +z."""
    k = M.lathe([(0, 0), (0.007, 0), (0.005, 0.012), (0.014, 0.022), (0.012, 0.03), (0, 0.031)], 14, sharp=(1,))
    p.add(mat, k.moved(M.rotate_x(math.pi / 2)).at(x, y, z))


def bookcase_books(rng, p: Parts, palette: list[str], x0: float, x1: float, y: float, room: float, d: float) -> None:
    """Books on a board from ``x0`` to ``x1`` at height ``y`` with ``room`` above: standing with their
    spines to the front (heights, thicknesses and depths of real books), a gap now and then, a few
    lying flat in a stack, the last ones of a row leaning."""
    x = x0 + float(rng.uniform(0.0, 0.06))
    while x < x1 - 0.02:
        r = rng.random()
        mat = palette[int(rng.integers(len(palette)))]
        off = (float(rng.uniform(0, 3)), float(rng.uniform(0, 3)))
        if r < 0.07:
            x += float(rng.uniform(0.05, 0.15))
        elif r < 0.14:
            bw, bd = float(rng.uniform(0.14, 0.21)), float(rng.uniform(0.15, max(0.16, d - 0.04)))
            if x + bw > x1:
                break
            yy = y
            for _ in range(int(rng.integers(2, 6))):
                th = float(rng.uniform(0.015, 0.04))
                if yy + th > y + room:
                    break
                m = palette[int(rng.integers(len(palette)))]
                p.add(m, M.rounded_box((bw / 2, th / 2 - 0.0003, bd / 2), 0.002, 1).at(
                    x + bw / 2 + float(rng.uniform(-0.005, 0.005)), yy + th / 2, 0.0), uv_offset=off)
                yy += th
            x += bw + 0.01
        else:
            th = float(rng.uniform(0.014, 0.055))
            bh = float(min(rng.uniform(0.16, 0.32), room))
            bd = float(rng.uniform(0.12, max(0.13, d - 0.03)))
            if x + th > x1 or bh < 0.08:
                x += th
                continue
            p.add(mat, M.rounded_box((th / 2 - 0.0006, bh / 2, bd / 2), 0.002, 1).at(
                x + th / 2, y + bh / 2, d / 2 - 0.015 - bd / 2), uv_offset=off)
            x += th


def shelf(rng, mats: MaterialPicker, name: str) -> Item:
    """A bookcase against a wall: plinth, sides, back, top, 3–6 boards filled with books."""
    w, d, h = _u(rng, 0.6, 1.4), _u(rng, 0.28, 0.38), _u(rng, 1.0, 2.1)
    body = mats.pick(str(rng.choice(["wood", "wood", "paint", "white"])))
    t, p = 0.02, Parts(name)
    p.add(body, M.box((0, h / 2, -d / 2 + 0.005), (w / 2 - t, h / 2 - 0.001, 0.005)))
    for sx in (-1, 1):
        p.add(body, M.bevel_box((sx * (w / 2 - t / 2), h / 2, 0), (t / 2, h / 2, d / 2), 0.002))
    p.add(body, M.bevel_box((0, h - t / 2, 0.003), (w / 2 + 0.008, t / 2, d / 2 + 0.003), 0.003))
    p.add(body, M.box((0, 0.03, d / 2 - 0.02), (w / 2 - t, 0.03, 0.009)))
    n = max(2, int(h / _u(rng, 0.3, 0.4)))
    ys = [0.06 + (h - 0.06 - t) * k / n for k in range(n + 1)]
    palette = [mats.pick("book") for _ in range(int(rng.integers(4, 9)))]
    for k, y in enumerate(ys[:-1]):
        p.add(body, M.bevel_box((0, y + t / 2, 0), (w / 2 - t, t / 2, d / 2 - 0.005), 0.002))
        bookcase_books(rng, p, palette, -w / 2 + t, w / 2 - t, y + t, ys[k + 1] - y - t - 0.015, d)
    return Item("shelf", p.shapes(), (w + 0.016, d + 0.006), h, [Surface(h, (0, 0), (w, d))], against_wall=True)
