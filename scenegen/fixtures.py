"""Light fixtures of real kinds, each kind one light group: ceiling panels, pendants, fluorescent
tubes, LED strips, floor and desk lamps with shades, screens.

Ceiling and wall fixtures are placed here in room coordinates; lamps that stand on the floor or a
table are :class:`scenegen.parts.Item` s placed like furniture (:mod:`scenegen.placement`). Emitting
parts are area emitters of the group (lamps: a glowing disk filling each opening of the shade —
the light a bulb sends out of it, without the firefly noise of a small bulb seen only via the
shade's inside — and, for fabric, paper and opal plastic shades, the shade's outer face glowing
with :data:`SHADE_GLOW` of the lamp's power; panels, battens ("tubes": their opal diffuser) and
strips: the emitting surface itself; screens: the picture). Emission is flat; the group's
``description`` names the kind and a typical illuminant (the service relights every group to any
illuminant anyway). Strengths are set by :func:`normalise_power` so that the groups of a room carry
comparable power. The fixtures are built not to make fireflies (``bench/SCENES.md``, "Fireflies"):
nothing sits millimetres in front of an emitter, and lamps light the room directly, not only by
bounce light.
"""

from __future__ import annotations

import math

import numpy as np

from illumix.scenegen import mesh as M
from illumix.scenegen.meshparts import Parts, mesh_area
from illumix.scenegen.parts import Item, MaterialPicker, box, disk, rect
from illumix.scenegen.rooms import Plan

KINDS = ("ceiling", "pendant", "tubes", "strip", "floor_lamp", "desk_lamp", "screen")
TYPICAL = {"ceiling": "LED panel, 4000 K", "pendant": "incandescent, 2700 K", "tubes": "fluorescent (F11 / FL3.x)",
           "strip": "LED strip, 3000 K", "floor_lamp": "incandescent / LED, 2700 K",
           "desk_lamp": "LED, 3000-4000 K", "screen": "display white, ~6500 K"}
ON_FLOOR, ON_SURFACE = ("floor_lamp",), ("desk_lamp",)


def _em(group: str) -> dict:
    return {"group": group, "strength": 1.0}


def _clear(c, half: tuple[float, float], avoid: list[tuple[float, float]], margin: float = 0.3) -> bool:
    """Whether no point of ``avoid`` (pendant cords) lies within ``margin`` of a ceiling fixture."""
    return all(abs(x - c[0]) > half[0] + margin or abs(z - c[2]) > half[1] + margin for x, z in avoid)


def ceiling_panels(rng, plan: Plan, mats: MaterialPicker, group: str,
                   avoid: list[tuple[float, float]] = ()) -> list[dict]:
    """1–2 panels per rectangle of the plan, centred on its long axis; none where a pendant hangs."""
    out = []
    housing = mats.pick("white")
    for i, (x0, z0, x1, z1) in enumerate(plan.rects):
        n = 1 if (x1 - x0) * (z1 - z0) < 12 else 2
        square = rng.random() < 0.6
        size = (0.6, 0.6) if square else (1.2, 0.3)
        for k in range(n):
            fx = (k + 1) / (n + 1) if (x1 - x0) >= (z1 - z0) else 0.5
            fz = 0.5 if (x1 - x0) >= (z1 - z0) else (k + 1) / (n + 1)
            c = (x0 + fx * (x1 - x0), plan.height - 0.012, z0 + fz * (z1 - z0))
            if not _clear(c, (size[0] / 2, size[1] / 2), avoid):
                continue
            out.append(rect(f"panel{i}_{k}", None, c, (0, -1, 0), (0, 0, -1), size, emitter=_em(group)))
            out.append(box(f"panel{i}_{k}_housing", housing, (c[0], plan.height - 0.006, c[2]),
                           (size[0] / 2 + 0.02, 0.0055, size[1] / 2 + 0.02)))
    return out


def pendants(rng, plan: Plan, mats: MaterialPicker, group: str, over: list[tuple[float, float]],
             hung: list[tuple[float, float]]) -> list[dict]:
    """1–3 pendants, over the given points (e.g. table centres) first, else over the rooms' centres;
    their ``(x, z)`` are appended to ``hung`` (ceiling panels and tubes keep clear of them)."""
    pts = list(over) or [((r[0] + r[2]) / 2, (r[1] + r[3]) / 2) for r in plan.rects]
    n = int(min(len(pts), rng.integers(1, 4)))
    shade, cord = mats.pick(str(rng.choice(["lampshade", "metal", "ceramic"]))), mats.pick("black")
    out = []
    for k, (x, z) in enumerate(pts[:n]):
        hung.append((x, z))
        r, hgt = float(rng.uniform(0.12, 0.25)), float(rng.uniform(0.18, 0.32))
        bottom = float(min(plan.height - 0.5, rng.uniform(1.85, 2.2)))
        p = Parts(f"pendant{k}")
        p.add(cord, M.rod((x, bottom + hgt, z), (x, plan.height, z), 0.006, 8))
        top = r * float(rng.uniform(0.25, 1.0))  # cone, bell or drum
        p.add(shade, M.lathe(shade_profile(r, top, hgt), 32).at(x, bottom, z))
        p.add(shade, M.lathe([(0, hgt - 0.004), (top, hgt - 0.004), (top, hgt), (0, hgt)], 32, sharp=(1, 2)).at(x, bottom, z))
        out += p.shapes() + [
            disk(f"pendant{k}_glow", None, (x, bottom + 0.02, z), (0, -1, 0), 0.9 * r, emitter=_em(group))]
        if shade.startswith("lampshade"):
            out.append(glowing_shade(f"pendant{k}", shade, r, top, hgt, bottom, group, math.pi * (0.9 * r) ** 2,
                                     at=(x, z)))
    return out


def tubes(rng, plan: Plan, mats: MaterialPicker, group: str, avoid: list[tuple[float, float]] = ()) -> list[dict]:
    """1–2 fluorescent battens under the ceiling per rectangle; none where a pendant hangs.

    A batten is a white powder-coated housing with an opal diffuser on its underside, and the
    diffuser is the emitter: a flat rectangle 7 cm wide facing down. The bare tube this replaced (a
    1.4 cm emitting cylinder 6 mm under a metal housing) lit the housing's underside from millimetres
    away, where sampling the tube by area misses the few centimetres that matter: 18 % of its group's
    light came as fireflies (``bench/SCENES.md``, "Fireflies"). Nothing lies behind the diffuser now."""
    out = []
    housing = mats.pick("white")
    for i, (x0, z0, x1, z1) in enumerate(plan.rects):
        along_x = (x1 - x0) >= (z1 - z0)
        length = float(min(1.5, 0.7 * max(x1 - x0, z1 - z0)))
        n = int(rng.integers(1, 3))
        for k in range(n):
            f = (k + 1) / (n + 1)
            cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
            if along_x:
                cz = z0 + f * (z1 - z0)
            else:
                cx = x0 + f * (x1 - x0)
            y = plan.height - 0.08
            d = np.array([length / 2, 0, 0]) if along_x else np.array([0, 0, length / 2])
            c = np.array([cx, y, cz])
            if not _clear(c, (d[0] + 0.06, d[2] + 0.06), avoid):
                continue
            axis = (1, 0, 0) if along_x else (0, 0, 1)
            out.append(rect(f"tube{i}_{k}", None, (cx, y - 0.001, cz), (0, -1, 0), axis, (0.07, length + 0.06),
                            emitter=_em(group)))
            half = (length / 2 + 0.05, 0.02, 0.05) if along_x else (0.05, 0.02, length / 2 + 0.05)
            out.append(box(f"tube{i}_{k}_housing", housing, (cx, y + 0.02, cz), half))
    return out


def strips(rng, plan: Plan, mats: MaterialPicker, group: str) -> list[dict]:
    """LED strips along the top of 1–3 walls (cove light), skipping openings: each on the front edge
    of a pelmet shelf 15.5 cm deep, 15 cm out from its wall and facing 45° down into the room — a
    cove strip set off its wall so that the wall is washed evenly. The strip the generator had first
    (6 cm from the wall, facing 17° off straight down) lit the wall just below it from centimetres
    away, a hot line that bounce paths sample as fireflies (``bench/SCENES.md``, "Fireflies"); the
    shelf stays behind the strip's emitting side (one reaching in front of it, lit from
    millimetres, brought them back)."""
    cands = [w for w in plan.walls if w.length > 1.5]
    out = []
    for k in rng.permutation(len(cands))[: int(rng.integers(1, 4))]:
        w = cands[int(k)]
        s0, s1 = 0.2, w.length - 0.2
        if any(o.y1 > plan.height - 0.3 for o in w.openings):
            continue
        off = 0.05 if w.partition else 0.0
        mid, shelf = w.point((s0 + s1) / 2, 0.15 + off), w.point((s0 + s1) / 2, 0.0775 + off)
        y = plan.height - 0.15
        n3 = (w.normal[0], 0.0, w.normal[1])
        down = np.array([n3[0], -1.0, n3[2]])
        out.append(rect(f"strip{len(out)}", None, (mid[0], y, mid[1]), tuple(down / np.linalg.norm(down)),
                        n3, (s1 - s0, 0.02), emitter=_em(group)))
        ledge = mats.pick("paint")
        out.append(box(f"strip{len(out)}_ledge", ledge, (shelf[0], y + 0.02, shelf[1]),
                       tuple(np.abs([(s1 - s0) / 2 * w.direction[0], 0, (s1 - s0) / 2 * w.direction[1]]) +
                             np.abs([0.0775 * n3[0], 0.01, 0.0775 * n3[2]]))))
    return out


def shade_profile(r_bottom: float, r_top: float, h: float, t: float = 0.003) -> list[tuple[float, float]]:
    """A lamp shade's closed lathe profile: a shell ``t`` thick from radius ``r_bottom`` at y = 0 to
    ``r_top`` at ``h``, open at both ends (a ring solid)."""
    return [(r_bottom, 0.0), (r_top, h), (r_top - t, h), (r_bottom - t, 0.0), (r_bottom, 0.0)]


SHADE_GLOW = 0.5  # share of a translucent-shade lamp's power that leaves through the shade itself


def glowing_shade(name: str, material: str, r_bottom: float, r_top: float, h: float, y0: float, group: str,
                  opening_area: float, at=(0.0, 0.0)) -> dict:
    """The outer face of a translucent (fabric, paper, opal plastic) shade as an emitter of ``group``: a frustum
    surface 0.5 mm outside the shade's shell from ``y0`` to ``y0 + h``, normals outward, carrying
    :data:`SHADE_GLOW` of the lamp's power (``opening_area``: m² of the glow disks in its openings,
    which emit at strength 1). A linen or paper shade transmits a good part of a bulb's light
    (it glows); drawn opaque, a lamp lit the room only through its openings — the ceiling above and
    a pool below — and everything else by bounce light, 0.5–0.9 relative noise at 64 spp."""
    m = M.lathe([(r_bottom + 0.0005, 0.0), (r_top + 0.0005, h)], 32)
    radial = m.v[m.f].mean(axis=1) * (1, 0, 1)
    if float(np.einsum("ij,ij->", m.face_normals(), radial)) < 0:  # the open surface: outward normals
        m = M.Mesh(m.v, m.f[:, ::-1].copy(), -m.n)
    p = Parts(f"{name}_shadeglow")
    p.add(material, m.at(at[0], y0, at[1]))
    area = math.pi * (r_bottom + r_top) * math.hypot(h, r_bottom - r_top)
    strength = SHADE_GLOW / (1 - SHADE_GLOW) * opening_area / area
    return p.shapes()[0] | {"emitter": {"group": group, "strength": round(strength, 6)}}


def floor_lamp(rng, mats: MaterialPicker, name: str, group: str) -> Item:
    """A floor lamp: a domed base, a pole, a drum or cone fabric shade glowing up, down and through."""
    r, hgt = float(rng.uniform(0.16, 0.25)), float(rng.uniform(1.35, 1.75))
    shade_h, top = float(rng.uniform(0.25, 0.35)), r * float(rng.uniform(0.6, 1.0))
    metal, shade, p = mats.pick(str(rng.choice(["metal", "black", "wood"]))), mats.pick("lampshade"), Parts(name)
    p.add(metal, M.lathe([(0, 0), (0.15, 0), (0.15, 0.012), (0.05, 0.035), (0.02, 0.04), (0, 0.04)], 32, sharp=(1, 2)))
    p.add(metal, M.rod((0, 0.04, 0), (0, hgt - shade_h / 2, 0), 0.012, 10))
    p.add(shade, M.lathe(shade_profile(r, top, shade_h), 32).at(0, hgt - shade_h, 0))
    down, up = 0.9 * r, 0.9 * top  # each opening glows over its whole width (a white inside)
    glow = glowing_shade(name, shade, r, top, shade_h, hgt - shade_h, group, math.pi * (down ** 2 + up ** 2))
    return Item("floor_lamp", p.shapes() + [glow,
        disk(f"{name}_glow_down", None, (0, hgt - shade_h + 0.02, 0), (0, -1, 0), down, emitter=_em(group)),
        disk(f"{name}_glow_up", None, (0, hgt - 0.02, 0), (0, 1, 0), up, emitter=_em(group)),
    ], footprint=(2 * r + 0.02, 2 * r + 0.02), height=hgt)


def desk_lamp(rng, mats: MaterialPicker, name: str, group: str) -> Item:
    """A table lamp: a turned base and stem with a drum shade, or a metal cone shade on a stem."""
    hgt, r = float(rng.uniform(0.35, 0.5)), float(rng.uniform(0.07, 0.11))
    metal, p = mats.pick(str(rng.choice(["metal", "ceramic", "black"]))), Parts(name)
    shade = mats.pick(str(rng.choice(["metal", "lampshade", "plastic"])))
    sh = 0.14
    prof = [(0, 0), (0.08, 0), (0.08, 0.012), (0.04, 0.03), (0.05, 0.09), (0.03, 0.15), (0.012, 0.17), (0.012, hgt - sh),
            (0, hgt - sh)]
    p.add(metal, M.lathe(prof, 24, sharp=(1, 2, 7)))
    top = r * float(rng.uniform(0.55, 0.9))
    p.add(shade, M.lathe(shade_profile(r, top, sh), 28).at(0, hgt - sh, 0))
    down, up = 0.9 * r, 0.9 * top  # each opening glows over its whole width (was 0.48 r: 3.5x the radiance)
    glows = [disk(f"{name}_glow", None, (0, hgt - sh + 0.02, 0), (0, -1, 0), down, emitter=_em(group)),
             disk(f"{name}_glow_up", None, (0, hgt - 0.02, 0), (0, 1, 0), up, emitter=_em(group))]
    if shade.startswith(("lampshade", "plastic")):  # fabric, paper and opal plastic glow; metal does not
        glows.append(glowing_shade(name, shade, r, top, sh, hgt - sh, group, math.pi * (down ** 2 + up ** 2)))
    return Item("desk_lamp", p.shapes() + glows, footprint=(2 * r + 0.02, 2 * r + 0.02), height=hgt)


def screen(rng, mats: MaterialPicker, name: str, group: str) -> Item:
    """A TV or monitor: frame box, emitting picture on its front (+z); kind ``screen`` hangs on a wall."""
    w = float(rng.uniform(0.6, 1.4))
    h = w * 9 / 16
    frame = mats.pick("screen_frame")
    return Item("screen", [
        box(f"{name}_frame", frame, (0, h / 2 + 0.02, 0.0), (w / 2 + 0.02, h / 2 + 0.02, 0.025)),
        rect(f"{name}_picture", None, (0, h / 2 + 0.02, 0.0265), (0, 0, 1), (0, 1, 0), (w, h), emitter=_em(group)),
    ], footprint=(w + 0.04, 0.06), height=h + 0.04, against_wall=True)


def emitting_area(shape: dict) -> float:
    """Area (m²) of an emitting shape document (rectangle, disk, sphere, cylinder, PLY mesh), for power."""
    if shape["type"] == "sphere":
        return 4 * math.pi * shape["radius"] ** 2
    if shape["type"] == "ply":
        return mesh_area(shape["filename"])
    if shape["type"] == "cylinder":
        return 2 * math.pi * shape["radius"] * float(np.linalg.norm(np.subtract(shape["p1"], shape["p0"])))
    m = np.asarray(shape["transform"]["matrix"])
    a, b = np.linalg.norm(m[:3, 0]), np.linalg.norm(m[:3, 1])
    return float(4 * a * b if shape["type"] == "rectangle" else math.pi * a * b)


def normalise_power(shapes: list[dict], lights: list[dict], groups: dict[str, float]) -> None:
    """Scale the strengths of each group's emitters (in place) so that the group emits ``groups[g]``
    (radiance × m² × π for areas, irradiance × m² for the sun through its window — the caller gives
    the sun's share as its own strength already scaled)."""
    for g, target in groups.items():
        ems = [s for s in shapes if s.get("emitter", {}).get("group") == g and not s["emitter"].get("portal")]
        power = sum(math.pi * emitting_area(s) * s["emitter"]["strength"] for s in ems)
        if power <= 0:
            continue
        k = target / power
        for s in ems:
            s["emitter"]["strength"] = round(s["emitter"]["strength"] * k, 4)
