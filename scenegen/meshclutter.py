"""Clutter as triangle meshes: lathed cups, mugs, bowls (with fruit), bottles, vases, jars and pots;
potted plants with leaf meshes; book stacks; framed pictures, wall shelves, clocks; rugs and
curtains.

Builders are ``(rng, mats, name) -> Item`` (:mod:`scenegen.parts`: origin at the centre of the
footprint, ``y = 0`` the surface it stands on, front ``+z``; hung items have their back at ``-z``).
Lathe profiles go from the axis at the bottom, out, over the rim and down the inside to the axis, so
vessels are closed solids with a wall thickness.
"""

from __future__ import annotations

import math

import numpy as np

from illumix.scenegen import mesh as M
from illumix.scenegen.meshparts import Parts
from illumix.scenegen.parts import Item, MaterialPicker, Surface, rect, sphere


def _u(rng, lo: float, hi: float) -> float:
    return round(float(rng.uniform(lo, hi)), 4)


def vessel_profile(r_base: float, r_belly: float, r_neck: float, r_lip: float, h: float, wall: float,
                   belly: float = 0.4, neck: float = 0.8) -> list[tuple[float, float]]:
    """A closed lathe profile of a vessel: base, belly at ``belly·h``, neck at ``neck·h``, lip, then the
    inside ``wall`` thick back down to a floor ``wall`` above the base."""
    out = [(0.0, 0.0), (r_base, 0.0)]
    ys = np.linspace(0, 1, 10)[1:]
    for t in ys:  # outside: smooth interpolation through base → belly → neck → lip
        r = np.interp(t, [0, belly, neck, 1.0], [r_base, r_belly, r_neck, r_lip])
        out.append((float(r), float(t * h)))
    inside = [(max(float(r) - wall, 0.002), float(y)) for r, y in out[:0:-1]]
    inside[0] = (inside[0][0], h - 0.001)
    inside[-1] = (inside[-1][0], wall)
    return out + inside + [(0.0, wall)]


def _vessel(rng, mats: MaterialPicker, name: str, kind: str, mat: str, r: float, h: float, shape) -> tuple[Parts, M.Mesh]:
    p = Parts(name)
    prof = vessel_profile(r * shape[0], r, r * shape[1], r * shape[2], h, 0.004, *shape[3:])
    m = M.lathe(prof, 28, sharp=(1, 10, 11, len(prof) - 2))
    p.add(mat, m)
    return p, m


def cup(rng, mats: MaterialPicker, name: str) -> Item:
    """A mug with a looped handle, or a cup on a saucer."""
    r, h = _u(rng, 0.035, 0.045), _u(rng, 0.075, 0.1)
    mat = mats.pick("ceramic")
    p, _ = _vessel(rng, mats, name, "cup", mat, r, h, (0.85, 1.0, 1.0, 0.4, 0.8))
    loop = [(0.028 + 0.006 * math.cos(a), 0.006 * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 9)]
    handle = M.lathe(loop, 16).moved(M.rotate_x(math.pi / 2)).moved(np.diag([0.7, 1.0, 1.0, 1.0]))
    p.add(mat, handle.at(r + 0.01, h * 0.55, 0))
    return Item("cup", p.shapes(), (2 * r + 0.06, 2 * r + 0.01), h)


def bowl(rng, mats: MaterialPicker, name: str) -> Item:
    """A bowl, often with fruit (food spectra) in it."""
    r, h = _u(rng, 0.09, 0.15), _u(rng, 0.05, 0.09)
    mat = mats.pick("ceramic")
    prof = [(0, 0), (r * 0.45, 0), (r * 0.5, 0.01)] + [
        (r * (0.5 + 0.5 * math.sin(t * math.pi / 2)), 0.01 + (h - 0.01) * (1 - math.cos(t * math.pi / 2)))
        for t in np.linspace(0.15, 1, 6)]
    inner = [(max(x - 0.005, 0.001), max(y, 0.012)) for x, y in prof[:1:-1]]
    full = prof + inner + [(0, 0.012)]
    p = Parts(name)
    p.add(mat, M.lathe(full, 32, sharp=(1, len(prof) - 1)))
    shapes = p.shapes()
    for i in range(int(rng.integers(0, 5))):
        fr = _u(rng, 0.028, 0.04)
        a, d = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(0, max(r * 0.45 - fr, 0.001)))
        y = 0.012 + fr + (0.05 if i >= 3 else 0.0)
        shapes.append(sphere(f"{name}_fruit{i}", mats.pick("food"), (d * math.cos(a), y, d * math.sin(a)), fr))
    return Item("bowl", shapes, (2 * r, 2 * r), h + 0.1)


def bottle(rng, mats: MaterialPicker, name: str) -> Item:
    """A bottle: body, rounded shoulder, neck and a cap."""
    r, h = _u(rng, 0.03, 0.045), _u(rng, 0.2, 0.32)
    body = mats.pick(str(rng.choice(["glass", "glass", "plastic", "ceramic"])))
    cap = mats.pick(str(rng.choice(["metal", "plastic", "black"])))
    neck, sh = 0.013, h * _u(rng, 0.55, 0.7)
    prof = [(0, 0), (r * 0.97, 0), (r, 0.01), (r, sh)] + [
        (neck + (r - neck) * math.cos(a), sh + (h * 0.85 - sh) * 0.5 * math.sin(a) * 1.0)
        for a in np.linspace(0.2, math.pi / 2, 5)] + [(neck, h - 0.02), (0, h - 0.02)]
    p = Parts(name)
    p.add(body, M.lathe(prof, 24, sharp=(1, len(prof) - 2)))
    p.add(cap, M.lathe([(0, h - 0.02), (neck + 0.002, h - 0.02), (neck + 0.002, h), (0, h)], 16, sharp=(1, 2)))
    return Item("bottle", p.shapes(), (2 * r, 2 * r), h)


def vase(rng, mats: MaterialPicker, name: str) -> Item:
    """A vase (lathed, varied silhouette), often with a few flowers."""
    r, h = _u(rng, 0.045, 0.08), _u(rng, 0.15, 0.35)
    mat = mats.pick(str(rng.choice(["ceramic", "ceramic", "glass"])))
    shape = (_u(rng, 0.5, 0.8), _u(rng, 0.35, 0.7), _u(rng, 0.45, 0.9), _u(rng, 0.25, 0.5), _u(rng, 0.65, 0.85))
    p, _ = _vessel(rng, mats, name, "vase", mat, r, h, shape)
    height = h
    if rng.random() < 0.6:
        petals = mats.pick(str(rng.choice(["food", "accent"])))
        for i in range(int(rng.integers(2, 5))):
            a = 2 * math.pi * i / 4 + float(rng.uniform(-0.3, 0.3))
            top = (0.5 * r * math.cos(a), h + float(rng.uniform(0.08, 0.18)), 0.5 * r * math.sin(a))
            p.add(mats.pick("plant"), M.rod((0, h * 0.6, 0), top, 0.003, 6))
            bloom = M.lathe([(0, -0.01), (0.02, 0.0), (0.025, 0.015), (0.0, 0.008)], 10, sharp=(2,))
            p.add(petals, bloom.at(*top))
            height = max(height, top[1] + 0.02)
    return Item("vase", p.shapes(), (2 * r + 0.04, 2 * r + 0.04), height)


def _rosette(rng, p: Parts, mats: MaterialPicker, y: float, n: int, length, width: float, up: float) -> float:
    """``n`` leaves round the stem at height ``y``, rising by ``up`` (rad) then drooping; returns the
    reach (m) from the stem."""
    leafm = [mats.pick("plant") for _ in range(2)]
    reach = 0.0
    for i in range(n):
        ln = float(rng.uniform(*length))
        lf = M.leaf(ln, width * float(rng.uniform(0.7, 1.2)), ln * float(rng.uniform(0.2, 0.6)))
        tilt = up * float(rng.uniform(0.6, 1.2))
        yaw = 2 * math.pi * (i * 0.382 % 1.0) + float(rng.uniform(-0.2, 0.2))
        lf = lf.moved(M.rotate_z(tilt)).moved(M.rotate_y(yaw))
        p.add(leafm[i % 2], lf.at(0, y + float(rng.uniform(0, 0.1)) * (i / n), 0))
        reach = max(reach, ln * math.cos(tilt))
    return reach


def plant(rng, mats: MaterialPicker, name: str) -> Item:
    """A pot plant for a table or shelf top: a lathed pot with soil, a rosette of leaves."""
    r, ph = _u(rng, 0.05, 0.08), _u(rng, 0.08, 0.13)
    pot = mats.pick(str(rng.choice(["ceramic", "ceramic", "plastic"])))
    p = Parts(name)
    p.add(pot, M.lathe(vessel_profile(r * 0.75, r, r, r, ph, 0.005, 0.7, 0.9), 24, sharp=(1, 10, 11)))
    p.add(mats.pick("soil"), M.lathe([(0, ph - 0.03), (r - 0.005, ph - 0.03), (r - 0.005, ph - 0.015), (0, ph - 0.01)], 24, sharp=(1, 2)))
    reach = _rosette(rng, p, mats, ph - 0.02, int(rng.integers(8, 16)), (0.08, 0.16), 0.045, 0.9)
    reach = min(reach, 0.16)
    return Item("plant", p.shapes(), (2 * reach + 0.04, 2 * reach + 0.04), ph + 0.2)


def floor_plant(rng, mats: MaterialPicker, name: str) -> Item:
    """A large plant in a floor pot: a trunk and two or three tiers of long leaves."""
    r, ph, th = _u(rng, 0.15, 0.22), _u(rng, 0.3, 0.45), _u(rng, 0.4, 0.9)
    pot = mats.pick(str(rng.choice(["ceramic", "plastic", "wood"])))
    p = Parts(name)
    p.add(pot, M.lathe(vessel_profile(r * 0.75, r, r, r * 1.05, ph, 0.01, 0.6, 0.9), 32, sharp=(1, 10, 11)))
    p.add(mats.pick("soil"), M.lathe([(0, ph - 0.05), (r - 0.01, ph - 0.05), (r - 0.01, ph - 0.03), (0, ph - 0.02)], 24, sharp=(1, 2)))
    p.add(mats.pick("wood"), M.rod((0, ph - 0.04, 0), (0.02, ph + th, 0.01), 0.018, 10))
    reach = 0.0
    for k in range(int(rng.integers(2, 4))):
        y = ph + th * (0.45 + 0.55 * k / 2)
        reach = max(reach, _rosette(rng, p, mats, y, int(rng.integers(6, 10)), (0.25, 0.45), 0.09, 0.7))
    reach = min(reach, 0.45)
    return Item("floor_plant", p.shapes(), (2 * reach, 2 * reach), ph + th + 0.35)


def book_stack(rng, mats: MaterialPicker, name: str) -> Item:
    bw, bd = _u(rng, 0.14, 0.22), _u(rng, 0.2, 0.28)
    p, y = Parts(name), 0.0
    for _ in range(int(rng.integers(1, 5))):
        t = _u(rng, 0.015, 0.045)
        dx, dz = float(rng.uniform(-0.01, 0.01)), float(rng.uniform(-0.01, 0.01))
        p.add(mats.pick("book"), M.rounded_box((bw / 2, t / 2 - 0.0003, bd / 2), 0.002, 1).at(dx, y + t / 2, dz),
              uv_offset=(float(rng.uniform(0, 3)), 0.0))
        y += t
    return Item("book_stack", p.shapes(), (bw + 0.02, bd + 0.02), y)


def storage_box(rng, mats: MaterialPicker, name: str) -> Item:
    w, d, h = _u(rng, 0.15, 0.35), _u(rng, 0.12, 0.3), _u(rng, 0.08, 0.25)
    m, p = mats.pick(str(rng.choice(["paper", "wood", "plastic", "fabric"]))), Parts(name)
    p.add(m, M.bevel_box((0, h / 2 - 0.006, 0), (w / 2 - 0.002, h / 2 - 0.006, d / 2 - 0.002), 0.003))
    p.add(m, M.bevel_box((0, h - 0.009, 0), (w / 2, 0.009, d / 2), 0.003))
    return Item("box", p.shapes(), (w, d), h)


def frame(rng, mats: MaterialPicker, name: str) -> Item:
    """A framed picture: moulded frame (swept, mitred), a pale mount and the picture texture."""
    w, h = _u(rng, 0.3, 1.0), _u(rng, 0.3, 0.8)
    border, depth = _u(rng, 0.025, 0.06), _u(rng, 0.02, 0.035)
    fm, p = mats.pick(str(rng.choice(["wood", "black", "metal", "white"]))), Parts(name)
    sec = [(0.0, 0.0), (border, 0.0), (border, depth * 0.8), (border * 0.7, depth), (border * 0.25, depth * 0.85),
           (0.0, depth * 0.55)]
    p.add(fm, M.frame_ring(w - 2 * border, h - 2 * border, sec).at(0, h / 2, -depth / 2))
    mount = rng.random() < 0.5
    inner = (w - 2 * border, h - 2 * border)
    pic = (inner[0] * 0.75, inner[1] * 0.75) if mount else inner
    p.add(mats.pick("paper") if mount else fm, M.box((0, h / 2, -depth / 2 + 0.002), (inner[0] / 2, inner[1] / 2, 0.002)))
    shapes = p.shapes() + [rect(f"{name}_picture", mats.pick("picture"), (0, h / 2, -depth / 2 + 0.0045), (0, 0, 1),
                                (0, 1, 0), pic)]
    return Item("frame", shapes, (w, depth), h, against_wall=True)


def clock(rng, mats: MaterialPicker, name: str) -> Item:
    r = _u(rng, 0.12, 0.2)
    rim, p = mats.pick(str(rng.choice(["metal", "black", "wood", "plastic"]))), Parts(name)
    ring = [(r - 0.012, 0.0), (r, 0.0), (r, 0.035), (r - 0.006, 0.045), (r - 0.012, 0.04), (r - 0.012, 0.0)]
    p.add(rim, M.lathe(ring, 48).moved(M.rotate_x(math.pi / 2)).at(0, r, -0.0225))
    p.add(mats.pick("paper"), M.lathe([(0, 0), (r - 0.011, 0), (r - 0.011, 0.01), (0, 0.01)], 48, sharp=(1, 2))
          .moved(M.rotate_x(math.pi / 2)).at(0, r, -0.0225))
    black = mats.pick("black")
    for k in range(12):
        a = 2 * math.pi * k / 12
        p.add(black, M.box((0.8 * r * math.sin(a), r + 0.8 * r * math.cos(a), -0.011), (0.004, 0.004, 0.001)))
    p.add(black, M.box((0, r + r * 0.3, -0.009), (0.004, r * 0.3, 0.0015)))
    p.add(black, M.box((r * 0.25, r, -0.006), (r * 0.25, 0.004, 0.0015)))
    return Item("clock", p.shapes(), (2 * r, 0.045), 2 * r, against_wall=True)


def wall_shelf(rng, mats: MaterialPicker, name: str) -> Item:
    """A floating wall shelf (a board on two brackets) whose top carries clutter."""
    w, d = _u(rng, 0.6, 1.2), _u(rng, 0.18, 0.26)
    board, p = mats.pick(str(rng.choice(["wood", "wood", "white", "paint"]))), Parts(name)
    bracket = mats.pick(str(rng.choice(["metal", "black"])))
    p.add(board, M.bevel_box((0, 0.2 - 0.012, 0), (w / 2, 0.012, d / 2), 0.003))
    tri = [(-d / 2, 0.0), (-d / 2, 0.176), (d / 2 - 0.03, 0.176)]  # (z, y) of the bracket's side
    for sx in (-1, 1):
        x = sx * (w / 2 - 0.08)
        p.add(bracket, M.extrude([(-z, y) for z, y in tri], x - 0.006, x + 0.006).moved(M.SIDE))
    return Item("wall_shelf", p.shapes(), (w, d), 0.2, [Surface(0.2, (0, 0), (w, d))], against_wall=True)


def rug(rng, mats: MaterialPicker, name: str) -> Item:
    """A rug: a thin slab with rounded edges, its pattern spanning it once (furniture may stand on it)."""
    w, d = _u(rng, 1.2, 2.5), _u(rng, 0.8, 1.8)
    p = Parts(name)
    p.add(mats.pick("rug"), M.rounded_box((w / 2, 0.004, d / 2), 0.003, 1).at(0, 0.004, 0), uv="unit")
    return Item("rug", p.shapes(), (w, d), 0.008)


def _drape(rng, width: float, height: float, amp: float, t: float = 0.004) -> M.Mesh:
    """A curtain panel: a strip gathered in folds of 8–14 cm, ``width`` wide, ``height`` long, its
    middle plane at z = 0 (a closed, smooth-sided extrusion)."""
    fold = float(rng.uniform(0.08, 0.14))
    xs = np.linspace(-width / 2, width / 2, max(8, int(width / fold * 8)))
    wave = amp * np.sin(2 * math.pi * (xs + width / 2) / fold)
    poly = np.concatenate([np.c_[xs, wave + t], np.c_[xs[::-1], wave[::-1] - t]])
    return M.extrude(poly, 0.0, height, smooth_sides=True).moved(M.rotate_x(-math.pi / 2))  # z up → y up


def curtain(rng, mats: MaterialPicker, name: str, width: float, height: float) -> Item:
    """A pair of curtains drawn to the sides of a window ``width`` wide (rod included), hanging
    ``height`` from the rod; back at ``-z``."""
    amp, p = float(rng.uniform(0.02, 0.035)), Parts(name)
    cloth, metal = mats.pick(str(rng.choice(["fabric", "linen"]))), mats.pick(str(rng.choice(["metal", "black", "wood"])))
    for sx in (-1, 1):
        pw = width * float(rng.uniform(0.2, 0.35))
        p.add(cloth, _drape(rng, pw, height - 0.04, amp).at(sx * (width / 2 - pw / 2), 0.0, 0.0), uv="unit")
    p.add(metal, M.rod((-width / 2, height - 0.02, 0.0), (width / 2, height - 0.02, 0.0), 0.011, 12))
    for sx in (-1, 1):
        p.add(metal, M.lathe([(0, 0), (0.016, 0.01), (0.018, 0.025), (0, 0.04)], 12).moved(
            M.rotate_z(-sx * math.pi / 2)).at(sx * width / 2, height - 0.02, 0.0))
    return Item("curtain", p.shapes(), (width + 0.1, 2 * amp + 0.03), height, against_wall=True)
