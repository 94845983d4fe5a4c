"""Furniture built from parametric parts: tables, desks, chairs, sofas, beds, cabinets, kitchen
counters and bookshelves filled with books.

Every builder is ``(rng, mats, name) -> Item`` (:mod:`scenegen.parts`): the item in its own frame —
origin at the centre of the footprint on the floor, front ``+z`` (where a person stands or sits),
back ``-z`` (the wall side for pieces that stand against a wall). Sizes are drawn from the ranges of
ordinary furniture (m; e.g. table tops 0.72–0.77 m high, seats 0.42–0.48 m, worktops 0.86–0.92 m).
``surfaces`` lists the free tops clutter may stand on; a shelf's books are part of the shelf itself.
Names of the parts are ``{name}_{part}``: the prefix before the first ``_`` is the object, which is
what the tests check intersections between.
"""

from __future__ import annotations

from illumix.scenegen.parts import Item, MaterialPicker, Surface, box, cylinder, disk


def _u(rng, lo: float, hi: float) -> float:
    return round(float(rng.uniform(lo, hi)), 4)


def _legs(name: str, mat: str, w: float, d: float, h: float, inset: float, t: float, round_legs: bool) -> list[dict]:
    """Four legs of height ``h`` under a ``w × d`` top, ``inset`` from its edges, thickness ``t``."""
    out = []
    for i, (sx, sz) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1))):
        x, z = sx * (w / 2 - inset - t / 2), sz * (d / 2 - inset - t / 2)
        if round_legs:
            out.append(cylinder(f"{name}_leg{i}", mat, (x, 0.0, z), (x, h, z), t / 2))
        else:
            out.append(box(f"{name}_leg{i}", mat, (x, h / 2, z), (t / 2, h / 2, t / 2)))
    return out


def table(rng, mats: MaterialPicker, name: str) -> Item:
    """A dining or kitchen table: rectangular on four legs, or round on a pedestal."""
    h, t = _u(rng, 0.72, 0.77), _u(rng, 0.025, 0.045)
    top = mats.pick(str(rng.choice(["wood", "wood", "plastic", "tile"])))
    if rng.random() < 0.3:  # round, on a central pedestal
        r = _u(rng, 0.45, 0.65)
        base = mats.pick(str(rng.choice(["metal", "wood", "black"])))
        shapes = [cylinder(f"{name}_top", top, (0, h - t, 0), (0, h, 0), r),
                  disk(f"{name}_topface", top, (0, h, 0), (0, 1, 0), r),
                  disk(f"{name}_under", top, (0, h - t, 0), (0, -1, 0), r),
                  cylinder(f"{name}_stem", base, (0, 0.03, 0), (0, h - t, 0), 0.04),
                  cylinder(f"{name}_foot", base, (0, 0, 0), (0, 0.03, 0), 0.28),
                  disk(f"{name}_footface", base, (0, 0.03, 0), (0, 1, 0), 0.28)]
        side = r * 2 ** 0.5  # the square inscribed in the top carries clutter
        return Item("table", shapes, (2 * r, 2 * r), h, [Surface(h, (0, 0), (side, side))])
    w = _u(rng, 0.9, 1.9)
    d = _u(rng, 0.7, min(1.0, w))
    leg = mats.pick(str(rng.choice(["wood", "metal", "black"]))) if rng.random() < 0.5 else top
    shapes = [box(f"{name}_top", top, (0, h - t / 2, 0), (w / 2, t / 2, d / 2))]
    shapes += _legs(name, leg, w, d, h - t, 0.04, _u(rng, 0.04, 0.07), bool(rng.random() < 0.4))
    return Item("table", shapes, (w, d), h, [Surface(h, (0, 0), (w, d))])


def desk(rng, mats: MaterialPicker, name: str) -> Item:
    """A desk against a wall: top on two side panels or legs, often with a drawer pedestal."""
    w, d, h, t = _u(rng, 1.0, 1.6), _u(rng, 0.55, 0.75), _u(rng, 0.72, 0.76), 0.03
    top = mats.pick(str(rng.choice(["wood", "plastic", "paint"])))
    shapes = [box(f"{name}_top", top, (0, h - t / 2, 0), (w / 2, t / 2, d / 2))]
    if rng.random() < 0.5:
        for i, sx in enumerate((-1, 1)):
            shapes.append(box(f"{name}_side{i}", top, (sx * (w / 2 - 0.015), (h - t) / 2, 0),
                              (0.015, (h - t) / 2, d / 2 - 0.01)))
    else:
        shapes += _legs(name, mats.pick(str(rng.choice(["metal", "black"]))), w, d, h - t, 0.03, 0.04, True)
    if rng.random() < 0.6:  # drawer pedestal on one side
        pw, sx = 0.4, float(rng.choice([-1, 1]))
        x = sx * (w / 2 - 0.05 - pw / 2)
        body = mats.pick(str(rng.choice(["paint", "plastic", "wood"])))
        handle = mats.pick("metal")
        shapes.append(box(f"{name}_pedestal", body, (x, (h - t) / 2, -0.02), (pw / 2, (h - t) / 2 - 0.005, d / 2 - 0.04)))
        for k in range(3):
            y = (h - t) * (k + 0.5) / 3
            shapes.append(box(f"{name}_handle{k}", handle, (x, y, d / 2 - 0.02 + 0.01), (0.06, 0.008, 0.01)))
    return Item("desk", shapes, (w, d), h, [Surface(h, (0, 0), (w, d))], against_wall=True)


def chair(rng, mats: MaterialPicker, name: str) -> Item:
    """A chair: seat, four legs, a backrest on the ``-z`` side (a person sitting faces ``+z``)."""
    w, d = _u(rng, 0.42, 0.5), _u(rng, 0.42, 0.5)
    sh, bh, t = _u(rng, 0.43, 0.48), _u(rng, 0.35, 0.5), 0.035
    frame = mats.pick(str(rng.choice(["wood", "wood", "metal", "plastic", "black"])))
    seat = mats.pick(str(rng.choice(["fabric", "leather"]))) if rng.random() < 0.5 else frame
    shapes = [box(f"{name}_seat", seat, (0, sh - t / 2, 0), (w / 2, t / 2, d / 2))]
    shapes += _legs(name, frame, w, d, sh - t, 0.01, 0.035, bool(rng.random() < 0.3))
    for i, sx in enumerate((-1, 1)):  # back posts continue the rear legs
        shapes.append(box(f"{name}_post{i}", frame, (sx * (w / 2 - 0.0275), sh + bh / 2, -d / 2 + 0.0275),
                          (0.0175, bh / 2, 0.0175)))
    shapes.append(box(f"{name}_back", seat if rng.random() < 0.5 else frame,
                      (0, sh + bh * 0.65, -d / 2 + 0.0275), (w / 2 - 0.045, bh * 0.3, 0.012)))
    return Item("chair", shapes, (w, d), sh + bh)


def sofa(rng, mats: MaterialPicker, name: str) -> Item:
    """A sofa against a wall: plinth, 2–3 seat cushions, back cushions, two arms."""
    seats = int(rng.integers(2, 4))
    arm = _u(rng, 0.12, 0.22)
    w, d = seats * _u(rng, 0.55, 0.7) + 2 * arm, _u(rng, 0.85, 1.0)
    sh, h = _u(rng, 0.4, 0.46), _u(rng, 0.75, 0.9)
    cover = mats.pick(str(rng.choice(["fabric", "fabric", "leather"])))
    cushion = cover if rng.random() < 0.7 else mats.pick("fabric")
    legs = mats.pick(str(rng.choice(["wood", "metal", "black"])))
    base_y = 0.1
    shapes = _legs(name, legs, w, d, base_y, 0.05, 0.04, True)
    shapes.append(box(f"{name}_base", cover, (0, (base_y + sh - 0.12) / 2, 0), (w / 2, (sh - 0.12 - base_y) / 2, d / 2)))
    back_d = 0.2
    inner = w - 2 * arm
    for i in range(seats):
        x = -inner / 2 + inner * (i + 0.5) / seats
        shapes.append(box(f"{name}_cushion{i}", cushion, (x, sh - 0.06, back_d / 2),
                          (inner / seats / 2 - 0.004, 0.06, (d - back_d) / 2 - 0.004)))
        shapes.append(box(f"{name}_backcushion{i}", cushion, (x, (sh + h) / 2, -d / 2 + back_d / 2),
                          (inner / seats / 2 - 0.004, (h - sh) / 2, back_d / 2)))
    for i, sx in enumerate((-1, 1)):
        shapes.append(box(f"{name}_arm{i}", cover, (sx * (w / 2 - arm / 2), (base_y + sh + 0.2) / 2, 0),
                          (arm / 2, (sh + 0.2 - base_y) / 2, d / 2)))
    return Item("sofa", shapes, (w, d), h, against_wall=True)


def bed(rng, mats: MaterialPicker, name: str) -> Item:
    """A bed with its head against a wall: frame, mattress, duvet, pillows and a headboard."""
    w = float(rng.choice([0.9, 1.2, 1.4, 1.6, 1.8]))
    d, fh, mh = _u(rng, 2.0, 2.15), _u(rng, 0.2, 0.32), _u(rng, 0.18, 0.25)
    frame = mats.pick(str(rng.choice(["wood", "wood", "paint", "fabric"])))
    linen, duvet = mats.pick("linen"), mats.pick(str(rng.choice(["linen", "fabric"])))
    top = fh + mh
    hb = _u(rng, 0.9, 1.2)
    shapes = [box(f"{name}_frame", frame, (0, fh / 2, 0), (w / 2, fh / 2, d / 2)),
              box(f"{name}_mattress", linen, (0, fh + mh / 2, 0.02), (w / 2 - 0.03, mh / 2, d / 2 - 0.06)),
              box(f"{name}_duvet", duvet, (0, top + 0.03, 0.25), (w / 2 - 0.01, 0.03, d / 2 - 0.3)),
              box(f"{name}_headboard", frame, (0, hb / 2, -d / 2 + 0.03), (w / 2, hb / 2, 0.03))]
    n_pillows = 1 if w < 1.3 else 2
    for i in range(n_pillows):
        x = -w / 2 + w * (i + 0.5) / n_pillows
        shapes.append(box(f"{name}_pillow{i}", linen, (x, top + 0.06, -d / 2 + 0.28),
                          (w / n_pillows / 2 - 0.08, 0.06, 0.18)))
    return Item("bed", shapes, (w, d), hb, against_wall=True)


def cabinet(rng, mats: MaterialPicker, name: str) -> Item:
    """A cabinet or sideboard against a wall: carcass on a plinth, doors with handles; its top carries
    clutter."""
    w, d, h = _u(rng, 0.6, 1.8), _u(rng, 0.38, 0.55), _u(rng, 0.5, 1.3)
    body = mats.pick(str(rng.choice(["wood", "paint", "plastic"])))
    front = body if rng.random() < 0.6 else mats.pick(str(rng.choice(["paint", "wood", "accent"])))
    handle = mats.pick(str(rng.choice(["metal", "black"])))
    plinth = 0.08
    shapes = [box(f"{name}_plinth", mats.pick("black"), (0, plinth / 2, 0.02), (w / 2 - 0.03, plinth / 2, d / 2 - 0.04)),
              box(f"{name}_body", body, (0, (plinth + h) / 2, -0.01), (w / 2, (h - plinth) / 2, d / 2 - 0.01))]
    doors = max(1, round(w / 0.45))
    for i in range(doors):
        x = -w / 2 + w * (i + 0.5) / doors
        shapes.append(box(f"{name}_door{i}", front, (x, (plinth + h) / 2, d / 2 - 0.01),
                          (w / doors / 2 - 0.003, (h - plinth) / 2 - 0.006, 0.01)))
        hx = x + (w / doors / 2 - 0.05) * (1 if i % 2 == 0 else -1)
        shapes.append(box(f"{name}_handle{i}", handle, (hx, h - 0.1, d / 2 + 0.008), (0.008, 0.05, 0.008)))
    return Item("cabinet", shapes, (w, d), h, [Surface(h, (0, 0), (w, d))], against_wall=True)


def kitchen_counter(rng, mats: MaterialPicker, name: str) -> Item:
    """A run of base units against a wall with a worktop, a sink and a hob."""
    w, d, h = _u(rng, 1.5, 3.0), 0.62, _u(rng, 0.86, 0.92)
    units = mats.pick(str(rng.choice(["paint", "plastic", "wood", "accent"])))
    top = mats.pick(str(rng.choice(["tile", "wood", "ceramic", "black"])))
    metal = mats.pick("metal")
    t, plinth = 0.04, 0.1
    shapes = [box(f"{name}_plinth", mats.pick("black"), (0, plinth / 2, -0.03), (w / 2, plinth / 2, d / 2 - 0.07)),
              box(f"{name}_units", units, (0, (plinth + h - t) / 2, -0.01), (w / 2, (h - t - plinth) / 2, d / 2 - 0.03)),
              box(f"{name}_worktop", top, (0, h - t / 2, 0), (w / 2, t / 2, d / 2))]
    doors = max(2, round(w / 0.6))
    for i in range(doors):
        x = -w / 2 + w * (i + 0.5) / doors
        shapes.append(box(f"{name}_handle{i}", metal, (x, h - t - 0.08, d / 2 - 0.02 + 0.008), (0.08, 0.008, 0.008)))
    sink_x = _u(rng, -w / 2 + 0.4, w / 2 - 0.4)
    shapes.append(box(f"{name}_sink", metal, (sink_x, h + 0.001, 0.02), (0.25, 0.001, 0.2)))
    shapes.append(cylinder(f"{name}_tap", metal, (sink_x, h, -0.22), (sink_x, h + 0.25, -0.22), 0.012))
    busy = [(sink_x - 0.3, sink_x + 0.3)]
    if w > 1.9:  # room for a hob at the end away from the sink
        hob_x = (w / 2 - 0.35) * (-1.0 if sink_x > 0 else 1.0)
        shapes.append(box(f"{name}_hob", mats.pick("black"), (hob_x, h + 0.002, 0.0), (0.29, 0.002, 0.25)))
        busy.append((hob_x - 0.32, hob_x + 0.32))
    free = _free_spans((-w / 2 + 0.02, w / 2 - 0.02), busy)
    a, b = max(free, key=lambda s: s[1] - s[0])
    surfaces = [Surface(h, ((a + b) / 2, 0.02), (b - a, d - 0.08))] if b - a > 0.2 else []
    return Item("kitchen_counter", shapes, (w, d), h + 0.25, surfaces, against_wall=True)


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


def shelf(rng, mats: MaterialPicker, name: str) -> Item:
    """A bookcase against a wall: sides, back, 3–6 boards filled with books (spines out, a few
    lying flat); its top carries clutter."""
    w, d, h = _u(rng, 0.6, 1.4), _u(rng, 0.28, 0.38), _u(rng, 1.0, 2.1)
    body = mats.pick(str(rng.choice(["wood", "wood", "paint", "white"])))
    t = 0.02
    shapes = [box(f"{name}_back", body, (0, h / 2, -d / 2 + 0.005), (w / 2, h / 2, 0.005))]
    for i, sx in enumerate((-1, 1)):
        shapes.append(box(f"{name}_side{i}", body, (sx * (w / 2 - t / 2), h / 2, 0), (t / 2, h / 2, d / 2)))
    n = max(2, int(h / _u(rng, 0.3, 0.4)))
    ys = [0.05 + (h - 0.05 - t) * k / n for k in range(n + 1)]
    palette = [mats.pick("book") for _ in range(int(rng.integers(3, 7)))]
    for k, y in enumerate(ys):
        shapes.append(box(f"{name}_board{k}", body, (0, y + t / 2, 0), (w / 2 - t, t / 2, d / 2 - 0.01)))
        if k < n:
            shapes += _books(rng, f"{name}_b{k}", palette, (-w / 2 + t, w / 2 - t), y + t, ys[k + 1] - y - t - 0.02, d)
    return Item("shelf", shapes, (w, d), h, [Surface(h, (0, 0), (w, d))], against_wall=True)


def _books(rng, name: str, palette: list[str], xs: tuple[float, float], y: float, room: float, d: float) -> list[dict]:
    """Books on a board from ``xs[0]`` to ``xs[1]`` at height ``y`` with ``room`` above them: mostly
    standing, spines to the front, with an occasional gap or a small stack lying flat."""
    out, x = [], xs[0] + float(rng.uniform(0.0, 0.1))
    while x < xs[1] - 0.02:
        r = rng.random()
        if r < 0.06:  # a gap
            x += float(rng.uniform(0.04, 0.15))
        elif r < 0.12:  # a stack lying flat
            bw, bd = float(rng.uniform(0.14, 0.2)), float(rng.uniform(0.15, max(0.16, d - 0.04)))
            if x + bw > xs[1]:
                break
            yy = y
            for _ in range(int(rng.integers(2, 5))):
                th = float(rng.uniform(0.015, 0.04))
                if yy + th > y + room:
                    break
                out.append(box(f"{name}_flat{len(out)}", palette[int(rng.integers(len(palette)))],
                               (x + bw / 2, yy + th / 2, 0.0), (bw / 2, th / 2, bd / 2)))
                yy += th
            x += bw + 0.01
        else:
            th = float(rng.uniform(0.015, 0.05))
            if x + th > xs[1]:
                break
            bh = float(min(rng.uniform(0.17, 0.3), room))
            bd = float(rng.uniform(0.13, max(0.14, d - 0.04)))
            if bh > 0.08:
                out.append(box(f"{name}_{len(out)}", palette[int(rng.integers(len(palette)))],
                               (x + th / 2, y + bh / 2, d / 2 - 0.02 - bd / 2), (th / 2 - 0.0005, bh / 2, bd / 2)))
            x += th
    return out


FURNITURE_BUILDERS = {"table": table, "desk": desk, "chair": chair, "sofa": sofa, "bed": bed,
                      "cabinet": cabinet, "kitchen_counter": kitchen_counter, "shelf": shelf}

