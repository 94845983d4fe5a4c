"""One procedural interior from a seed: plan → windows and daylight → window joinery → furniture →
light fixtures → clutter → dressing (curtains, a closed door, something on every wall and every top,
a plank or tile floor) → power balance → views (chosen by the mixed-light probe) → a validated
scene document. Objects are triangle meshes (:mod:`scenegen.meshfurniture`,
:mod:`scenegen.appliances`, :mod:`scenegen.meshclutter`) kept as PLY files under
``$ILLUMIX_CACHE/scenegen-meshes`` (:mod:`scenegen.meshparts`); walls, ceilings and emitters stay
primitives.

``generate_doc(seed, config)`` is deterministic in ``(GENERATOR_VERSION, seed, config)``: every
random draw comes from one ``numpy`` generator seeded with both. The document carries
``generator = {"name": "illumix.scenegen", "version": ..., "seed": ...}`` (copied into every cube's
metadata by the render jobs). ``layout_hash(doc)`` — sha256 of the geometry, materials and lights:
two rooms are distinct when their hashes differ.

Light groups: ``daylight`` when the room has windows (sun + sky portals, :mod:`scenegen.windows`),
plus 1–3 artificial groups of distinct kinds (:mod:`scenegen.fixtures`), 2–4 groups in all — a kind
that finds no place (a desk lamp without a top, strips without a free wall) is replaced by another
until two groups light the room — each
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
from illumix.scenegen import dressing
from illumix.scenegen import fixtures as fx
from illumix.scenegen.materials import Materials
from illumix.scenegen.placement import Placer
from illumix.scenegen.rooms import LAYOUTS, make_plan, shell_shapes
from illumix.scenegen.views import MixedLightRule
from illumix.scenegen.windows import add_windows, daylight

ROOM_TYPES: dict[str, list[str]] = {
    "living": ["sofa", "coffee_table", "table", "chair", "chair", "shelf", "cabinet", "shelf"],
    "bedroom": ["bed", "cabinet", "shelf", "desk", "chair", "cabinet"],
    "kitchen": ["kitchen_counter", "fridge", "oven", "table", "chair", "chair", "cabinet", "washing_machine"],
    "office": ["desk", "chair", "shelf", "shelf", "cabinet", "sofa", "coffee_table"],
    "dining": ["table", "chair", "chair", "chair", "chair", "cabinet", "shelf"],
}
ONCE = ("bed", "kitchen_counter", "fridge", "oven", "washing_machine", "coffee_table")  # one to a room
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
    # a kept view's least mixed light (probe): candidates below it are dropped
    mixed_light: MixedLightRule = Field(default_factory=MixedLightRule)

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
        more = [k for k in names if k not in ONCE]
        names += list(rng.choice(more, size=int(area // 6)))  # bigger rooms, more furniture
        for kind in names:
            name = _obj(kind, n)
            item = FURNITURE[kind](rng, mats, name)
            n += 1
            if kind == "chair" and tables:
                got = _chair_at_table(rng, placer, item, name, tables[-1])
            elif item.against_wall:
                got = placer.against_wall(item, name)
            elif kind == "coffee_table" and any(p.kind == "sofa" for p in placer.placed):
                got = _in_front(rng, placer, item, name, next(p for p in placer.placed if p.kind == "sofa"))
            elif kind == "table":  # room for chairs round it, which stand close (they are placed next)
                got = placer.free_standing(item, name, clearance=0.75, mark=0.02) or placer.free_standing(item, name)
            else:
                got = placer.free_standing(item, name)
            if got is None:
                continue
            shapes += got
            if kind in ("table", "desk"):
                p = placer.placed[-1]
                tables.append((p.x, p.z, p.item.footprint, p.turns))
    return [(t[0], t[1]) for t in tables]


def _in_front(rng, placer: Placer, item, name: str, of) -> list[dict] | None:
    """Stand ``item`` 35–45 cm in front of the placed item ``of`` (a coffee table before a sofa),
    turned like it; anywhere free near it otherwise."""
    from illumix.scenegen.parts import rotation_y

    f = rotation_y(of.turns) @ [0, 0, 1, 0]
    dist = of.item.footprint[1] / 2 + float(rng.uniform(0.35, 0.45)) + item.footprint[1] / 2
    got = placer.facing(item, name, of.x + f[0] * dist, of.z + f[2] * dist, of.turns)
    return got if got is not None else placer.free_standing(item, name, near=(of.x, of.z))


def _chair_at_table(rng, placer: Placer, chair, name: str, table) -> list[dict] | None:
    """Stand ``chair`` at a free place round ``table`` (one per 0.6 m of each side), facing it."""
    x, z, (w, d), k = table
    ex, ez = (d, w) if k % 2 else (w, d)
    gap = chair.footprint[1] / 2 + 0.08  # the occupancy grid rounds both boxes out to its 5 cm cells
    sides = ((ex, 2, lambda t: (x + t, z + ez / 2 + gap)), (ex, 0, lambda t: (x + t, z - ez / 2 - gap)),
             (ez, 3, lambda t: (x + ex / 2 + gap, z + t)), (ez, 1, lambda t: (x - ex / 2 - gap, z + t)))
    spots = []
    for length, turn, at in sides:  # chair centres along each side, turned to face the table
        n = max(1, int(length / 0.6))
        spots += [(at((i + 0.5) / n * length - length / 2), turn) for i in range(n)]
    for i in rng.permutation(len(spots)):
        (cx, cz), turn = spots[int(i)]
        got = placer.facing(chair, name, cx, cz, turn)
        if got is not None:
            return got
    return placer.free_standing(chair, name, near=(x, z))


def _light_groups(rng, plan, placer: Placer, mats: Materials, shapes: list[dict], tables, n_art: int,
                  n_day: int) -> list[dict]:
    """``n_art`` artificial groups of distinct kinds; when fewer than two groups would light the room
    (a kind that found no place: no top for a desk lamp, no free wall for a strip), more kinds are
    tried until two do — ceiling panels, which always fit, last."""
    kinds = [str(k) for k in rng.choice(fx.KINDS, size=n_art, replace=False)]
    kinds.sort(key=lambda k: k != "pendant")  # pendants first: panels and tubes keep clear of them
    groups, hung = [], []
    for kind in kinds:
        groups += _one_group(rng, plan, placer, mats, shapes, tables, kind, hung)
    spare = [k for k in ("floor_lamp", "tubes", "pendant", "strip", "ceiling") if k not in kinds]
    while len(groups) + n_day < 2 and spare:
        groups += _one_group(rng, plan, placer, mats, shapes, tables, spare.pop(0), [] if not spare else hung)
    return groups


def _one_group(rng, plan, placer: Placer, mats: Materials, shapes: list[dict], tables, kind: str,
               hung: list) -> list[dict]:
    """The fixtures of one artificial group of ``kind`` (appended to ``shapes``): ``[group]``, or ``[]``
    when none found a place."""
    g = kind.replace("_", "-")
    before = len(shapes)
    if kind == "ceiling":
        shapes += fx.ceiling_panels(rng, plan, mats, g, hung)
    elif kind == "pendant":
        shapes += fx.pendants(rng, plan, mats, g, tables, hung)
    elif kind == "tubes":
        shapes += fx.tubes(rng, plan, mats, g, hung)
    elif kind == "strip":
        shapes += fx.strips(rng, plan, mats, g)
    else:
        for i in range(int(rng.integers(1, 3))):
            item = getattr(fx, kind)(rng, mats, f"{g}{i}", g)
            got = (placer.against_wall(item, item.kind) if kind == "floor_lamp" else
                   placer.on_surface(item, item.kind) if kind == "desk_lamp" else
                   placer.hang(item, item.kind, (1.1, 1.6)))
            if got is None and kind == "floor_lamp":
                got = placer.free_standing(item, item.kind, clearance=0.1)
            shapes += got or []
    if not any(s.get("emitter", {}).get("group") == g for s in shapes[before:]):
        return []
    return [{"name": g, "kind": "artificial", "description": f"{kind.replace('_', ' ')}; typical: {fx.TYPICAL[kind]}"}]


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
    shapes = [s for s in shell_shapes(plan, shell) if not s["name"].startswith("floor")]
    wood = mats.docs[shell["floor"]]["reflectance"].get("pattern") == "wood"
    shapes += dressing.floors(rng, plan, shell["floor"], wood)
    portals, lights, day = daylight(rng, plan, windows)
    shapes += portals
    placer = Placer(plan, rng)
    shapes += dressing.window_frames(rng, plan, placer, mats, windows)
    shapes += dressing.doorways(plan, mats, shell["ceiling"])
    tables = _furnish(rng, plan, placer, mats, shapes)
    shapes += dressing.kitchen_wall_units(rng, plan, placer, mats)
    n_art = int(rng.integers(1, 4)) if day else int(rng.integers(2, 4))
    groups = ([day] if day else []) + _light_groups(rng, plan, placer, mats, shapes, tables, n_art, int(bool(day)))
    _clutter(rng, placer, mats, shapes)
    shapes += dressing.curtains(rng, plan, placer, mats, windows)
    shapes += dressing.doors(rng, plan, placer, mats)
    shapes += dressing.walls(rng, plan, placer, mats)
    shapes += dressing.tops(rng, placer, mats)
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
    import warnings

    from illumix.scene.load import scene_from_dict
    from illumix.scenegen.views import clear_views, probe_views

    scene = scene_from_dict(doc, source=doc["name"], check=False)
    res = probe_views(scene, rule=config.mixed_light)
    frac, shares = res.mixed, res.shares
    clear = clear_views(scene, [v["name"] for v in doc["views"]])
    # clear views (they see their target, no wall fills them) first, then those that see at least two
    # groups (each >= 5 % of the view's light), then by mixed fraction; only views the mixed-light
    # rule keeps, unless none does: then the best one, and the room says so
    two = (shares >= GROUP_SEEN).sum(axis=1) >= 2
    ranked = np.lexsort((-frac, ~two, ~clear))
    order = [i for i in ranked if res.keep[i]][:n_views]
    met = bool(order)
    if not met:
        order = [int(np.argmax(res.two_group))]
        warnings.warn(f"{doc['name']}: no candidate view has {config.mixed_light.min_fraction:.0%} of its pixels "
                      f"lit by two groups each above {config.mixed_light.min_share:.0%}; kept the most mixed one "
                      f"({res.two_group[order[0]]:.0%})", UserWarning, stacklevel=3)
    doc["generator"]["views_dropped"] = int((~res.keep).sum())
    doc["generator"]["mixed_light_rule_met"] = met
    doc["views"] = [dict(doc["views"][i], name=f"view{k}") for k, i in enumerate(sorted(order))]
    doc["description"] += "; mixed-light fraction per view " + ", ".join(f"{frac[i]:.2f}" for i in sorted(order))
    return doc


def generate_scene(seed: int, config: GeneratorConfig = GeneratorConfig()):
    """The validated :class:`~scene.model.Scene` of room ``seed``."""
    from illumix.scene.load import scene_from_dict

    return scene_from_dict(generate_doc(seed, config), source=f"generated room (seed {seed})")


def layout_hash(doc: dict) -> str:
    """sha256 of a document's geometry, materials, lights and groups (mesh files by name, not by the
    folder they are kept in: their names are their contents' hashes)."""
    key = {k: doc.get(k) for k in ("shapes", "materials", "lights", "light_groups")}
    key["shapes"] = [dict(s, filename=s["filename"].rsplit("/", 1)[-1]) if "filename" in s else s
                     for s in key["shapes"] or []]
    return hashlib.sha256(json.dumps(key, sort_keys=True, default=float).encode()).hexdigest()
