"""Placement without intersections: items on the floor (against a wall or free-standing), on the
tops of other items, and hung on walls.

The floor is an occupancy grid (:data:`CELL` m cells) over the plan: cells outside the rooms, in
the partition's thickness and in front of doors are blocked from the start; every placed item
blocks its footprint (plus a clearance). Tops of placed items (:class:`scenegen.parts.Surface`, in
room coordinates) take clutter packed as non-overlapping rectangles. Each wall keeps the spans
taken by items standing against it (with their heights) and by hung items, so a picture never hangs
behind a tall shelf and nothing tall stands in front of a window.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from illumix.scenegen.parts import Item, footprint_extent, place, rotation_y
from illumix.scenegen.rooms import PARTITION, Plan

CELL = 0.05  # m


@dataclass
class PlacedSurface:
    """A free top in room coordinates: height, centre ``(x, z)``, size ``(w, d)``; what stands on it."""

    y: float
    center: tuple[float, float]
    size: tuple[float, float]
    owner: str
    taken: list[tuple[float, float, float, float]] = field(default_factory=list)


@dataclass
class Placed:
    name: str
    kind: str
    x: float
    z: float
    turns: int
    item: Item
    y: float = 0.0  # what it stands on (floor 0, a top, a hung item's bottom)


def quarter_turns_facing(normal: tuple[float, float]) -> int:
    """The turn that points an item's front (+z) along ``normal`` (an axis direction ``(x, z)``)."""
    for k in range(4):
        f = rotation_y(k) @ [0, 0, 1, 0]
        if abs(f[0] - normal[0]) < 1e-6 and abs(f[2] - normal[1]) < 1e-6:
            return k
    raise ValueError(f"normal {normal} is not an axis direction")


class Placer:
    def __init__(self, plan: Plan, rng: np.random.Generator):
        self.plan, self.rng = plan, rng
        x0, z0, x1, z1 = plan.bounds()
        self.origin = np.array([x0, z0])
        self.shape = (int(np.ceil((x1 - x0) / CELL)), int(np.ceil((z1 - z0) / CELL)))
        cx = x0 + (np.arange(self.shape[0]) + 0.5) * CELL
        cz = z0 + (np.arange(self.shape[1]) + 0.5) * CELL
        X, Z = np.meshgrid(cx, cz, indexing="ij")
        inside = np.zeros(self.shape, bool)
        for r in plan.rects:
            inside |= (X >= r[0]) & (X <= r[2]) & (Z >= r[1]) & (Z <= r[3])
        self.free = inside.copy()
        for w in plan.walls:
            if w.partition:  # the partition's thickness
                self._block_wall_band(w, PARTITION / 2 + 0.01)
        for lo, hi, n in plan.doors:  # keep the doorway passable: 0.9 m both sides
            a, b = np.minimum(lo, hi) - np.abs(n) * 0.9, np.maximum(lo, hi) + np.abs(n) * 0.9
            self._mark((a[0], a[1], b[0], b[1]), False)
        self.placed: list[Placed] = []
        self.surfaces: list[PlacedSurface] = []
        self.wall_spans: dict[int, list[tuple[float, float, float, float]]] = {}  # s0, s1, y0, y1
        self.boxes: list[np.ndarray] = []  # (2, 3) bounds of hung items and of things on tops
        self.opening_spans: set[tuple] = set()  # (wall, s0, s1, y0, y1) of window joinery: curtains may cover it

    def _box3(self, item: Item, x: float, z: float, k: int, y: float) -> np.ndarray:
        ex, ez = footprint_extent(item, k)
        return np.array([[x - ex / 2, y, z - ez / 2], [x + ex / 2, y + item.height, z + ez / 2]])

    @staticmethod
    def _overlap(b: np.ndarray, o: np.ndarray) -> bool:
        return bool(np.all(np.minimum(b[1], o[1]) - np.maximum(b[0], o[0]) > 1e-3))

    def _clashes(self, b: np.ndarray) -> bool:
        return any(self._overlap(b, o) for o in self.boxes)

    # -- grid -----------------------------------------------------------------------------------
    def _idx(self, box):
        i0 = int(np.floor((box[0] - self.origin[0]) / CELL))
        j0 = int(np.floor((box[1] - self.origin[1]) / CELL))
        i1 = int(np.ceil((box[2] - self.origin[0]) / CELL))
        j1 = int(np.ceil((box[3] - self.origin[1]) / CELL))
        return i0, j0, i1, j1

    def _mark(self, box, value: bool) -> None:
        i0, j0, i1, j1 = self._idx(box)
        self.free[max(i0, 0):max(i1, 0), max(j0, 0):max(j1, 0)] = value

    def _block_wall_band(self, w, depth: float) -> None:
        a, b = np.asarray(w.p0), np.asarray(w.p1)
        n = np.asarray(w.normal)
        pts = np.array([a, b, a + n * depth, b + n * depth])
        self._mark((*pts.min(axis=0), *pts.max(axis=0)), False)

    def is_free(self, box) -> bool:
        i0, j0, i1, j1 = self._idx(box)
        if i0 < 0 or j0 < 0 or i1 > self.shape[0] or j1 > self.shape[1]:
            return False
        return bool(self.free[i0:i1, j0:j1].all())

    def clearance_map(self) -> np.ndarray:
        """Distance (m) from each cell to the nearest blocked cell."""
        import cv2

        pad = np.pad(self.free, 1).astype(np.uint8)
        return cv2.distanceTransform(pad, cv2.DIST_L2, 5)[1:-1, 1:-1] * CELL

    def cell_center(self, i: int, j: int) -> tuple[float, float]:
        return float(self.origin[0] + (i + 0.5) * CELL), float(self.origin[1] + (j + 0.5) * CELL)

    # -- placing --------------------------------------------------------------------------------
    def _commit(self, item: Item, name: str, x: float, z: float, k: int, clearance: float, y: float = 0.0):
        ex, ez = footprint_extent(item, k)
        if y == 0.0 and item.kind != "rug":
            self._mark((x - ex / 2 - clearance, z - ez / 2 - clearance, x + ex / 2 + clearance,
                        z + ez / 2 + clearance), False)
        self.placed.append(Placed(name, item.kind, x, z, k, item, y))
        m = rotation_y(k)
        for s in item.surfaces:
            if s.size[0] <= 0 or s.size[1] <= 0:
                continue
            c = m @ [s.center[0], 0, s.center[1], 0]
            size = (s.size[1], s.size[0]) if k % 2 else s.size
            self.surfaces.append(PlacedSurface(y + s.y, (x + c[0], z + c[2]), size, name))
        return place(item, x, z, k, "", y)

    def against_wall(self, item: Item, name: str, tries: int = 40) -> list[dict] | None:
        """Stand ``item`` with its back to a random wall; None when no spot is free."""
        ex_w, ex_d = item.footprint
        for _ in range(tries):
            wi = int(self.rng.integers(len(self.plan.walls)))
            w = self.plan.walls[wi]
            if w.length < ex_w + 0.3:
                continue
            s0 = float(self.rng.uniform(0.1, w.length - ex_w - 0.1))
            if any(o.kind == "window" and item.height > o.y0 - 0.05 and not (s0 + ex_w <= o.s0 or s0 >= o.s1)
                   for o in w.openings):
                continue
            if any(not (s0 + ex_w <= a or s0 >= b) and item.height > y0 for a, b, y0, _ in self.wall_spans.get(wi, [])):
                continue
            off = ex_d / 2 + 0.01 + (PARTITION / 2 if w.partition else 0.0)
            c = w.point(s0 + ex_w / 2, off)
            k = quarter_turns_facing(w.normal)
            ex, ez = footprint_extent(item, k)
            if not self.is_free((c[0] - ex / 2, c[1] - ez / 2, c[0] + ex / 2, c[1] + ez / 2)):
                continue
            self.wall_spans.setdefault(wi, []).append((s0, s0 + ex_w, 0.0, item.height))
            return self._commit(item, name, float(c[0]), float(c[1]), k, 0.05)
        return None

    def free_standing(self, item: Item, name: str, near: tuple[float, float] | None = None,
                      clearance: float = 0.3, tries: int = 40, mark: float | None = None) -> list[dict] | None:
        """Stand ``item`` anywhere free (turned by a random quarter), near a point if given, with
        ``clearance`` free round it; ``mark``: the margin then blocked (default ``clearance``; less for
        a table whose chairs come next)."""
        x0, z0, x1, z1 = self.plan.bounds()
        for _ in range(tries):
            k = int(self.rng.integers(4))
            ex, ez = footprint_extent(item, k)
            if near is None:
                x, z = self.rng.uniform(x0 + ex / 2, x1 - ex / 2), self.rng.uniform(z0 + ez / 2, z1 - ez / 2)
            else:
                x, z = near[0] + self.rng.normal(0, 0.6), near[1] + self.rng.normal(0, 0.6)
            box = (x - ex / 2 - clearance, z - ez / 2 - clearance, x + ex / 2 + clearance, z + ez / 2 + clearance)
            if item.kind == "rug" or self.is_free(box):
                keep = clearance if mark is None else mark
                return self._commit(item, name, float(x), float(z), k, keep if item.kind != "rug" else 0.0)
        return None

    def facing(self, item: Item, name: str, x: float, z: float, k: int) -> list[dict] | None:
        """Stand ``item`` exactly at ``(x, z)`` turned by ``k`` if that is free (chairs at a table)."""
        ex, ez = footprint_extent(item, k)
        if not self.is_free((x - ex / 2, z - ez / 2, x + ex / 2, z + ez / 2)):
            return None
        return self._commit(item, name, x, z, k, 0.02)

    def on_surface(self, item: Item, name: str, tries: int = 12,
                   only: PlacedSurface | None = None) -> list[dict] | None:
        """Stand ``item`` on a random free top (``only`` that one, if given; no overlap with what stands
        there already)."""
        ok = [s for s in (self.surfaces if only is None else [only]) if s.size[0] >= item.footprint[0] + 0.04 and s.size[1] >= item.footprint[1] + 0.04
              and s.y + item.height < self.plan.height - 0.3]
        for _ in range(tries if ok else 0):
            s = ok[int(self.rng.integers(len(ok)))]
            k = int(self.rng.integers(4))
            ex, ez = footprint_extent(item, k)
            if ex > s.size[0] - 0.02 or ez > s.size[1] - 0.02:
                continue
            x = s.center[0] + self.rng.uniform(-(s.size[0] - ex) / 2 + 0.01, (s.size[0] - ex) / 2 - 0.01)
            z = s.center[1] + self.rng.uniform(-(s.size[1] - ez) / 2 + 0.01, (s.size[1] - ez) / 2 - 0.01)
            box = (x - ex / 2, z - ez / 2, x + ex / 2, z + ez / 2)
            if any(not (box[2] <= t[0] or box[0] >= t[2] or box[3] <= t[1] or box[1] >= t[3]) for t in s.taken):
                continue
            b3 = self._box3(item, float(x), float(z), k, s.y)
            if self._clashes(b3):
                continue
            self.boxes.append(b3)
            s.taken.append(box)
            self.placed.append(Placed(name, item.kind, float(x), float(z), k, item, s.y))
            return place(item, float(x), float(z), k, "", s.y + 0.0005)
        return None

    def hang(self, item: Item, name: str, y_range=(1.2, 1.7), tries: int = 30,
             walls: list[int] | None = None) -> list[dict] | None:
        """Hang ``item`` (front +z) on a wall (one of ``walls`` if given) where no opening, hung item or
        taller standing item is; its tops (a wall shelf's board) take clutter."""
        w_w = item.footprint[0]
        pool = list(range(len(self.plan.walls))) if walls is None else list(walls)
        for _ in range(tries if pool else 0):
            wi = pool[int(self.rng.integers(len(pool)))]
            w = self.plan.walls[wi]
            if w.length < w_w + 0.4:
                continue
            s0 = float(self.rng.uniform(0.2, w.length - w_w - 0.2))
            y0 = float(self.rng.uniform(*y_range)) - item.height / 2
            y1 = y0 + item.height
            if y1 > self.plan.height - 0.2 or not w.free(s0, s0 + w_w, margin=0.1):
                continue
            if any(not (s0 + w_w <= a or s0 >= b) and not (y1 <= b0 - 0.02 or y0 >= b1 + 0.02)
                   for a, b, b0, b1 in self.wall_spans.get(wi, [])):
                continue
            off = item.footprint[1] / 2 + 0.002 + (PARTITION / 2 if w.partition else 0.0)
            c = w.point(s0 + w_w / 2, off)
            k = quarter_turns_facing(w.normal)
            b3 = self._box3(item, float(c[0]), float(c[1]), k, y0)
            if self._clashes(b3):
                continue
            self.boxes.append(b3)
            self.wall_spans.setdefault(wi, []).append((s0, s0 + w_w, y0, y1))
            self._add_surfaces(item, name, float(c[0]), float(c[1]), k, y0)
            self.placed.append(Placed(name, item.kind, float(c[0]), float(c[1]), k, item, y0))
            return place(item, float(c[0]), float(c[1]), k, "", y0)
        return None

    def _add_surfaces(self, item: Item, name: str, x: float, z: float, k: int, y: float) -> None:
        m = rotation_y(k)
        for s in item.surfaces:
            if s.size[0] > 0 and s.size[1] > 0:
                c = m @ [s.center[0], 0, s.center[1], 0]
                size = (s.size[1], s.size[0]) if k % 2 else s.size
                self.surfaces.append(PlacedSurface(y + s.y, (x + c[0], z + c[2]), size, name))

    def at_wall(self, item: Item, name: str, wi: int, s0: float, y0: float, gap: float = 0.002,
                keep: float = 0.0, over_openings: bool = False) -> list[dict] | None:
        """Put ``item`` at ``s0`` along wall ``wi`` (its left edge), bottom at ``y0``, back ``gap`` off the
        wall — doors and curtains, where the caller chose the spot — when that spot is free: no
        standing or hung item in the way, nothing on the floor in front of it (``keep`` m more in
        front: a door's swing). Openings are the caller's business."""
        w = self.plan.walls[wi]
        w_w, y1 = item.footprint[0], y0 + item.height
        if s0 < 0 or s0 + w_w > w.length:
            return None
        if any(not (s0 + w_w <= a or s0 >= b) and not (y1 <= b0 or y0 >= b1) and
               (not over_openings or (wi, a, b, b0, b1) not in self.opening_spans)
               for a, b, b0, b1 in self.wall_spans.get(wi, [])):
            return None
        if not over_openings and any(not (s0 + w_w <= o.s0 or s0 >= o.s1) and not (y1 <= o.y0 or y0 >= o.y1)
                                     for o in w.openings):
            return None
        off = item.footprint[1] / 2 + gap + (PARTITION / 2 if w.partition else 0.0)
        c = w.point(s0 + w_w / 2, off)
        k = quarter_turns_facing(w.normal)
        b3 = self._box3(item, float(c[0]), float(c[1]), k, y0)
        if self._clashes(b3) or any(self._overlap(b3, self._box3(p.item, p.x, p.z, p.turns, p.y))
                                    for p in self.placed if p.kind != "rug"):
            return None
        if y0 < 0.3:  # reaches the floor: the floor in front must be free, and stays free
            base = PARTITION / 2 + 0.02 if w.partition else 0.0
            front = [w.point(s0, base), w.point(s0 + w_w, base + item.footprint[1] + gap + keep + 0.05)]
            box = (*np.minimum(*front), *np.maximum(*front))
            if not self.is_free(box):
                return None
            self._mark(box, False)
        self.boxes.append(b3)
        self.wall_spans.setdefault(wi, []).append((s0, s0 + w_w, y0, y1))
        self.placed.append(Placed(name, item.kind, float(c[0]), float(c[1]), k, item, y0))
        return place(item, float(c[0]), float(c[1]), k, "", y0)
