"""One procedural interior from a seed: plan → windows and daylight → furniture → light fixtures →
clutter → power balance → views (chosen by the mixed-light probe) → a validated scene document.

``generate_doc(seed, config)`` is deterministic in ``(GENERATOR_VERSION, seed, config)``: every
random draw comes from one ``numpy`` generator seeded with both. The document carries
``generator = {"name": "illumix.scenegen", "version": ..., "seed": ...}`` (copied into every cube's
metadata by the render jobs). ``layout_hash(doc)`` — sha256 of the geometry, materials and lights:
two rooms are distinct when their hashes differ.

Light groups: ``daylight`` when the room has windows (sun + sky portals, :mod:`scenegen.windows`),
plus 1–3 artificial groups of distinct kinds (:mod:`scenegen.fixtures`), 2–4 groups in all, each
declaring its ``kind`` (``daylight`` / ``artificial``: what ``pair=`` maps its illuminants by). Each
group's total emitted power is drawn around a common level (log-normal, σ = 0.5) scaled with the
floor area, so that no group routinely drowns the others — mixing is the point of the data.
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from illumix.scenegen import GENERATOR_VERSION
from illumix.scenegen import fixtures as fx
from illumix.scenegen.materials import Materials
from illumix.scenegen.placement import Placer
from illumix.scenegen.rooms import LAYOUTS, make_plan, shell_shapes
from illumix.scenegen.windows import add_windows, daylight

ROOM_TYPES: dict[str, list[str]] = {
    "living": ["sofa", "table", "shelf", "cabinet", "chair"],
    "bedroom": ["bed", "cabinet", "shelf", "desk", "chair"],
    "kitchen": ["kitchen_counter", "table", "chair", "cabinet"],
    "office": ["desk", "chair", "shelf", "cabinet"],
    "dining": ["table", "chair", "cabinet", "shelf"],
}
GROUP_SEEN = 0.05  # a view "sees" a group that brings at least this share of its light (probe)
POWER_PER_M2 = 6.0  # a group's mean emitted power per m² of floor (radiance × m² × π, flat emission)


class GeneratorConfig(BaseModel):
    """What varies between generated rooms (the dataset config's ``generator`` section)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    layouts: list[str] = Field(default_factory=lambda: list(LAYOUTS))
    windows: tuple[int, int] = (0, 3)
    views: tuple[int, int] = (3, 7)
    resolution: tuple[int, int] = (240, 180)
    probe: bool = True  # choose views by a probe render's mixed-light fraction
    candidates: int = Field(default=16, ge=1, le=64)  # candidate views the probe chooses from

    @model_validator(mode="after")
    def _check(self) -> GeneratorConfig:
        bad = [x for x in self.layouts if x not in LAYOUTS]
        if bad or not self.layouts:
            raise ValueError(f"layouts: unknown {bad}; choose from {', '.join(LAYOUTS)}")
        if not 0 <= self.windows[0] <= self.windows[1] <= 3:
            raise ValueError("windows: give [min, max] with 0 <= min <= max <= 3")
        if not 1 <= self.views[0] <= self.views[1] <= 16:
            raise ValueError("views: give [min, max] with 1 <= min <= max <= 16")
        if min(self.resolution) < 1:
            raise ValueError("resolution: give [width, height], both >= 1")
        return self


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(GENERATOR_VERSION), 0x5CE9E])


def _obj(kind: str, i: int) -> str:
    """An object's name: its shapes are ``{name}_{part}``, so the name itself has no ``_``."""
    return f"{kind.replace('_', '-')}{i}"


def _furnish(rng, plan, placer: Placer, mats: Materials, shapes: list[dict]) -> list[tuple[float, float]]:
    """Furniture for every room (by a drawn room type); returns table centres (pendants hang there)."""
    from illumix.scenegen.catalog import FURNITURE

    tables = []
    n = 0
    for room in sorted(set(plan.rooms)):
        rtype = str(rng.choice(list(ROOM_TYPES)))
        area = sum((r[2] - r[0]) * (r[3] - r[1]) for r, k in zip(plan.rects, plan.rooms) if k == room)
        names = list(ROOM_TYPES[rtype])
        names += list(rng.choice(names, size=int(area // 8)))  # bigger rooms, more furniture
        for kind in names:
            name = _obj(kind, n)
            item = FURNITURE[kind](rng, mats, name)
            n += 1
            if kind == "chair" and tables:
                got = _chair_at_table(rng, placer, item, name, tables[-1])
            elif item.against_wall:
                got = placer.against_wall(item, name)
            else:
                got = placer.free_standing(item, name)
            if got is None:
                continue
            shapes += got
            if kind in ("table", "desk"):
                p = placer.placed[-1]
                tables.append((p.x, p.z, p.item.footprint, p.turns))
    return [(t[0], t[1]) for t in tables]


def _chair_at_table(rng, placer: Placer, chair, name: str, table) -> list[dict] | None:
    x, z, (w, d), k = table
    ex, ez = (d, w) if k % 2 else (w, d)
    sides = [((x, z + ez / 2 + 0.25), 2), ((x, z - ez / 2 - 0.25), 0), ((x + ex / 2 + 0.25, z), 3),
             ((x - ex / 2 - 0.25, z), 1)]
    for i in rng.permutation(4):
        (cx, cz), turn = sides[int(i)]
        got = placer.facing(chair, name, cx, cz, turn)
        if got is not None:
            return got
    return placer.free_standing(chair, name, near=(x, z))


def _light_groups(rng, plan, placer: Placer, mats: Materials, shapes: list[dict], tables, n_art: int) -> list[dict]:
    kinds = list(rng.choice(fx.KINDS, size=n_art, replace=False))
    kinds.sort(key=lambda k: k != "pendant")  # pendants first: panels and tubes keep clear of them
    groups, hung = [], []
    for kind in kinds:
        g = str(kind).replace("_", "-")
        before = len(shapes)
        if kind == "ceiling":
            shapes += fx.ceiling_panels(rng, plan, mats, g, hung)
        elif kind == "pendant":
            shapes += fx.pendants(rng, plan, mats, g, tables, hung)
        elif kind == "tubes":
            shapes += fx.tubes(rng, plan, mats, g, hung)
        elif kind == "strip":
            shapes += fx.strips(rng, plan, mats, g)
        elif kind in ("floor_lamp", "desk_lamp", "screen"):
            for i in range(int(rng.integers(1, 3))):
                build = getattr(fx, str(kind))
                item = build(rng, mats, f"{g}{i}", g)
                got = (placer.against_wall(item, item.kind) if kind == "floor_lamp" else
                       placer.on_surface(item, item.kind) if kind == "desk_lamp" else
                       placer.hang(item, item.kind, (1.1, 1.6)))
                if got is None and kind == "floor_lamp":
                    got = placer.free_standing(item, item.kind, clearance=0.1)
                shapes += got or []
        if any(s.get("emitter", {}).get("group") == g for s in shapes[before:]):
            groups.append({"name": g, "kind": "artificial",
                           "description": f"{kind.replace('_', ' ')}; typical: {fx.TYPICAL[kind]}"})
    return groups


def _clutter(rng, placer: Placer, mats: Materials, shapes: list[dict]) -> None:
    from illumix.scenegen.catalog import CLUTTER, FLOOR_CLUTTER, TABLETOP, WALL_ITEMS

    for i in range(int(rng.integers(3, 9)) + len(placer.surfaces)):
        kind = TABLETOP[int(rng.integers(len(TABLETOP)))]
        item = CLUTTER[kind](rng, mats, _obj(kind, i))
        got = placer.on_surface(item, _obj(kind, i))
        shapes += [dict(s, name=f"c{i}_{s['name']}") for s in (got or [])]
    for i in range(int(rng.integers(1, 4))):
        kind = WALL_ITEMS[int(rng.integers(len(WALL_ITEMS)))]
        got = placer.hang(CLUTTER[kind](rng, mats, _obj(kind, i)), _obj(kind, i))
        shapes += [dict(s, name=f"w{i}_{s['name']}") for s in (got or [])]
    for i in range(int(rng.integers(0, 3))):
        kind = FLOOR_CLUTTER[int(rng.integers(len(FLOOR_CLUTTER)))]
        item = CLUTTER[kind](rng, mats, _obj(kind, i))  # unprefixed: no furniture has these kinds
        got = placer.free_standing(item, _obj(kind, i), clearance=0.05) if item.kind == "rug" else \
            placer.against_wall(item, _obj(kind, i))
        shapes += got or []


def _balance(rng, plan, shapes: list[dict], lights: list[dict], groups: list[dict]) -> None:
    """Each group's power around ``POWER_PER_M2 × floor area`` (log-normal σ 0.5); screens stay dim."""
    level = POWER_PER_M2 * plan.area
    targets = {}
    for g in groups:
        k = level * math.exp(float(rng.normal(0, 0.5)))
        if g["name"] == "daylight":
            sky = [s for s in shapes if s.get("emitter", {}).get("group") == "daylight"]
            a = sum(fx.emitting_area(s) for s in sky)
            # sky portals emit π L A; the sun through a window about E A cos θ — split the level 1 : 2,
            # with cos θ ≈ 2/3 (sun 20–55° high, ±35° off the wall normal: cos elev · cos azim ≈ 0.6–0.9)
            for s in sky:
                s["emitter"]["strength"] = round(k / 3 / (math.pi * a), 4)
            for light in lights:
                light["strength"] = round(2 * k / 3 / max(a, 1e-6) / (2 / 3), 4)
        elif g["name"] == "screen":
            targets[g["name"]] = 0.15 * k
        else:
            targets[g["name"]] = k
    fx.normalise_power(shapes, lights, targets)


def generate_doc(seed: int, config: GeneratorConfig = GeneratorConfig()) -> dict:
    """The scene document of room ``seed`` (see module docstring)."""
    rng = _rng(seed)
    plan = make_plan(rng, str(rng.choice(config.layouts)))
    windows = add_windows(rng, plan, int(rng.integers(config.windows[0], config.windows[1] + 1)))
    mats = Materials(rng)
    shell = {"floor": mats.pick("floor"), "ceiling": mats.pick("ceiling")}
    for room in set(plan.rooms):
        shell[f"wall{room}"] = mats.pick("accent" if rng.random() < 0.2 else "paint")
    shapes = shell_shapes(plan, shell)
    portals, lights, day = daylight(rng, plan, windows)
    shapes += portals
    placer = Placer(plan, rng)
    tables = _furnish(rng, plan, placer, mats, shapes)
    n_art = int(rng.integers(1, 4)) if day else int(rng.integers(2, 4))
    groups = ([day] if day else []) + _light_groups(rng, plan, placer, mats, shapes, tables, n_art)
    _clutter(rng, placer, mats, shapes)
    _balance(rng, plan, shapes, lights, groups)
    interest = [(p.x, min(p.item.height, 1.5) * 0.6, p.z) for p in placer.placed]
    interest += [((r[0] + r[2]) / 2, 1.0, (r[1] + r[3]) / 2) for r in plan.rects]
    n_cand = config.candidates if config.probe else config.views[1]
    from illumix.scenegen.views import candidates

    views = candidates(rng, placer, n_cand, interest, config.resolution)
    n_views = int(rng.integers(config.views[0], config.views[1] + 1))
    layout = {"rect": "rectangular room", "L": "L-shaped room", "two-rooms": "two rooms joined by a door"}
    kind = layout[_layout_of(plan)]
    doc = {
        "name": f"room-{seed:06d}",
        "description": (f"illumix.scenegen {GENERATOR_VERSION}, seed {seed}: {kind}, {plan.area:.1f} m², "
                        f"ceiling {plan.height:.2f} m, {len(windows)} window(s), groups "
                        f"{', '.join(g['name'] for g in groups)}"),
        "materials": mats.docs,
        "shapes": shapes,
        "lights": lights,
        "light_groups": groups,
        "views": views,
        "max_depth": 8,
        "generator": {"name": "illumix.scenegen", "version": GENERATOR_VERSION, "seed": int(seed)},
    }
    return _choose_views(doc, n_views, config)


def _layout_of(plan) -> str:
    if len(set(plan.rooms)) > 1:
        return "two-rooms"
    return "L" if len(plan.rects) > 1 else "rect"


def _choose_views(doc: dict, n_views: int, config: GeneratorConfig) -> dict:
    """Keep the ``n_views`` candidates with the largest mixed-light fraction (probe), or the first ones."""
    if not config.probe or len(doc["views"]) <= 1:
        doc["views"] = doc["views"][:n_views]
        return doc
    from illumix.scene.load import scene_from_dict
    from illumix.scenegen.views import clear_views, probe

    scene = scene_from_dict(doc, source=doc["name"], check=False)
    frac, shares = probe(scene)
    clear = clear_views(scene, [v["name"] for v in doc["views"]])
    # clear views (they see their target, no wall fills them) first, then those that see at least two
    # groups (each >= 5 % of the view's light), then by mixed fraction
    two = (shares >= GROUP_SEEN).sum(axis=1) >= 2
    order = np.lexsort((-frac, ~two, ~clear))[:n_views]
    doc["views"] = [dict(doc["views"][i], name=f"view{k}") for k, i in enumerate(sorted(order))]
    doc["description"] += "; mixed-light fraction per view " + ", ".join(f"{frac[i]:.2f}" for i in sorted(order))
    return doc


def generate_scene(seed: int, config: GeneratorConfig = GeneratorConfig()):
    """The validated :class:`~scene.model.Scene` of room ``seed``."""
    from illumix.scene.load import scene_from_dict

    return scene_from_dict(generate_doc(seed, config), source=f"generated room (seed {seed})")


def layout_hash(doc: dict) -> str:
    """sha256 of a document's geometry, materials, lights and groups."""
    key = {k: doc.get(k) for k in ("shapes", "materials", "lights", "light_groups")}
    return hashlib.sha256(json.dumps(key, sort_keys=True, default=float).encode()).hexdigest()
