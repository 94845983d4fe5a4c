"""Floor plans and the room shell: floors, ceilings and walls with openings.

A plan is a set of non-overlapping axis-aligned rectangles ``(x0, z0, x1, z1)`` (metres, y up), each
labelled with the room it belongs to: one rectangle (``rect``), two forming an L (``L``), or two
rooms side by side whose shared wall has a door opening (``two-rooms``). The walls are the boundary
of the union (cell edges of the plan's coordinate grid between inside and outside, merged into
straight runs), each with its inward normal; the partition between two rooms is a wall too, seen
from both sides. Openings (windows, doors) are cut out of a wall as the rectangles around them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from illumix.scenegen.parts import rect

LAYOUTS = ("rect", "L", "two-rooms")
DOOR = (0.9, 2.05)  # width, height (m)
PARTITION = 0.1  # thickness of the wall between two rooms (m): its faces sit half of it into each room


@dataclass
class Opening:
    """A hole in a wall: ``s0 … s1`` along the wall (m from its start), ``y0 … y1`` high."""

    s0: float
    s1: float
    y0: float
    y1: float
    kind: str  # "window" | "door"


@dataclass
class Wall:
    """A straight wall run from ``p0`` to ``p1`` (``(x, z)``) with its inward normal (``(x, z)``);
    ``partition``: between two rooms (inward is only one side of it)."""

    p0: tuple[float, float]
    p1: tuple[float, float]
    normal: tuple[float, float]
    room: int
    partition: bool = False
    openings: list[Opening] = field(default_factory=list)

    @property
    def length(self) -> float:
        return float(np.hypot(self.p1[0] - self.p0[0], self.p1[1] - self.p0[1]))

    @property
    def direction(self) -> np.ndarray:
        d = np.subtract(self.p1, self.p0)
        return d / np.linalg.norm(d)

    def point(self, s: float, offset: float = 0.0) -> np.ndarray:
        """The floor point ``(x, z)`` at ``s`` along the wall, ``offset`` into the room."""
        return np.asarray(self.p0) + self.direction * s + np.asarray(self.normal) * offset

    def free(self, s0: float, s1: float, margin: float = 0.15) -> bool:
        """True when ``s0 … s1`` (plus margin) overlaps no opening and stays off the wall's ends."""
        if s0 < margin or s1 > self.length - margin:
            return False
        return all(s1 + margin <= o.s0 or s0 - margin >= o.s1 for o in self.openings)


@dataclass
class Plan:
    rects: list[tuple[float, float, float, float]]
    rooms: list[int]
    height: float
    walls: list[Wall] = field(default_factory=list)
    doors: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)  # (lo, hi, normal) (x, z)

    @property
    def area(self) -> float:
        return float(sum((r[2] - r[0]) * (r[3] - r[1]) for r in self.rects))

    def room_of(self, x: float, z: float) -> int | None:
        for r, k in zip(self.rects, self.rooms):
            if r[0] <= x <= r[2] and r[1] <= z <= r[3]:
                return k
        return None

    def bounds(self) -> tuple[float, float, float, float]:
        a = np.asarray(self.rects)
        return float(a[:, 0].min()), float(a[:, 1].min()), float(a[:, 2].max()), float(a[:, 3].max())


def make_plan(rng: np.random.Generator, layout: str) -> Plan:
    """A floor plan of ``layout`` (:data:`LAYOUTS`) with its walls, centred near the origin."""
    h = float(rng.uniform(2.4, 3.2))
    if layout == "rect":
        w, d = rng.uniform(3.0, 7.0), rng.uniform(3.0, 6.0)
        rects, rooms = [(0.0, 0.0, w, d)], [0]
    elif layout == "L":
        w, d = rng.uniform(4.0, 7.0), rng.uniform(3.0, 5.0)
        wb, db = rng.uniform(2.2, w - 1.5), rng.uniform(1.8, 3.5)
        rects, rooms = [(0.0, 0.0, w, d), (0.0, d, wb, d + db)], [0, 0]
    elif layout == "two-rooms":
        w1, d1 = rng.uniform(3.0, 5.5), rng.uniform(3.0, 5.5)
        w2, d2 = rng.uniform(2.5, 5.0), rng.uniform(2.5, 5.5)
        z2 = rng.uniform(-(d2 - 1.5), d1 - 1.5)
        rects, rooms = [(0.0, 0.0, w1, d1), (w1, z2, w1 + w2, z2 + d2)], [0, 1]
    else:
        raise ValueError(f"unknown layout {layout!r}; choose one of {', '.join(LAYOUTS)}")
    # Mirror and centre: varied orientation without changing the shape.
    a = np.asarray(rects, dtype=float)
    if rng.random() < 0.5:
        a[:, [0, 2]] = -a[:, [2, 0]]
    if rng.random() < 0.5:
        a[:, [1, 3]] = -a[:, [3, 1]]
    c = np.array([(a[:, 0].min() + a[:, 2].max()) / 2, (a[:, 1].min() + a[:, 3].max()) / 2])
    a[:, [0, 2]] -= c[0]
    a[:, [1, 3]] -= c[1]
    plan = Plan([tuple(float(v) for v in np.round(r, 4)) for r in a], rooms, round(h, 4))
    plan.walls = _walls(plan)
    if layout == "two-rooms":
        _add_door(rng, plan)
    return plan


def _walls(plan: Plan) -> list[Wall]:
    xs = sorted({r[0] for r in plan.rects} | {r[2] for r in plan.rects})
    zs = sorted({r[1] for r in plan.rects} | {r[3] for r in plan.rects})
    nx, nz = len(xs) - 1, len(zs) - 1
    cell = np.full((nx + 2, nz + 2), -1, dtype=int)  # room id, -1 outside; padded by one
    for i in range(nx):
        for j in range(nz):
            k = plan.room_of((xs[i] + xs[i + 1]) / 2, (zs[j] + zs[j + 1]) / 2)
            cell[i + 1, j + 1] = -1 if k is None else k
    edges: list[tuple] = []  # (p0, p1, normal, room, partition)
    for i in range(nx + 1):  # vertical cell edges x = xs[i], between cells i and i+1 (padded indices)
        for j in range(nz):
            a, b = cell[i, j + 1], cell[i + 1, j + 1]
            p0, p1 = (xs[i], zs[j]), (xs[i], zs[j + 1])
            if a != b:
                if b >= 0:
                    edges.append((p0, p1, (1.0, 0.0), int(b), bool(a >= 0)))
                if a >= 0:
                    edges.append((p0, p1, (-1.0, 0.0), int(a), bool(b >= 0)))
    for j in range(nz + 1):
        for i in range(nx):
            a, b = cell[i + 1, j], cell[i + 1, j + 1]
            p0, p1 = (xs[i], zs[j]), (xs[i + 1], zs[j])
            if a != b:
                if b >= 0:
                    edges.append((p0, p1, (0.0, 1.0), int(b), bool(a >= 0)))
                if a >= 0:
                    edges.append((p0, p1, (0.0, -1.0), int(a), bool(b >= 0)))
    # Merge collinear neighbours with the same normal and room.
    edges.sort(key=lambda e: (e[2], e[3], e[4], e[0][0] if e[2][0] else e[0][1], e[0]))
    walls: list[Wall] = []
    for p0, p1, n, k, part in edges:
        last = walls[-1] if walls else None
        if last and last.normal == n and last.room == k and last.partition == part and \
                np.allclose(last.p1, p0):
            last.p1 = p1
        else:
            walls.append(Wall(p0, p1, n, k, part))
    return [w for w in walls if w.length > 1e-6]


def _add_door(rng: np.random.Generator, plan: Plan) -> None:
    """A door in the partition: the same opening cut in both of its faces."""
    parts = [w for w in plan.walls if w.partition]
    if not parts:
        return
    w0 = max(parts, key=lambda w: w.length)
    s = float(rng.uniform(0.3, max(0.31, w0.length - DOOR[0] - 0.3)))
    lo, hi = sorted((w0.point(s), w0.point(s + DOOR[0])), key=lambda p: tuple(p))
    for w in parts:
        # the partition's two faces run the same segment; cut the opening where it lies on each
        if np.allclose(np.abs(w.normal), np.abs(w0.normal)):
            a = float(np.dot(lo - np.asarray(w.p0), w.direction))
            b = float(np.dot(hi - np.asarray(w.p0), w.direction))
            a, b = sorted((a, b))
            if 0 <= a and b <= w.length + 1e-9:
                w.openings.append(Opening(a, b, 0.0, DOOR[1], "door"))
    plan.doors.append((lo, hi, np.asarray(w0.normal)))


def shell_shapes(plan: Plan, mats: dict[str, str]) -> list[dict]:
    """Floor, ceiling and wall rectangles. ``mats``: material names for ``floor``, ``ceiling`` and
    ``wall<room>`` (e.g. ``wall0``, ``wall1``)."""
    h = plan.height
    out: list[dict] = []
    for i, (x0, z0, x1, z1) in enumerate(plan.rects):
        c, size = ((x0 + x1) / 2, (z0 + z1) / 2), (x1 - x0, z1 - z0)
        out.append(rect(f"floor{i}", mats["floor"], (c[0], 0.0, c[1]), (0, 1, 0), (0, 0, -1), size))
        out.append(rect(f"ceiling{i}", mats["ceiling"], (c[0], h, c[1]), (0, -1, 0), (0, 0, -1), size))
    for i, w in enumerate(plan.walls):
        out += wall_pieces(w, h, mats[f"wall{w.room}"], f"wall{i}", PARTITION / 2 if w.partition else 0.0)
    for i, (lo, hi, n) in enumerate(plan.doors):  # the door's jambs and lintel across the partition
        n3, t = (n[0], 0.0, n[1]), PARTITION
        along = (hi - lo) / np.linalg.norm(hi - lo)
        for k, (p, sign) in enumerate(((lo, 1.0), (hi, -1.0))):
            out.append(rect(f"door{i}_jamb{k}", mats["ceiling"], (p[0], DOOR[1] / 2, p[1]),
                            (along[0] * sign, 0.0, along[1] * sign), (0, 1, 0), (t, DOOR[1])))
        mid = (lo + hi) / 2
        out.append(rect(f"door{i}_lintel", mats["ceiling"], (mid[0], DOOR[1], mid[1]), (0, -1, 0), n3,
                        (float(np.linalg.norm(hi - lo)), t)))
    return out


def wall_pieces(w: Wall, h: float, material: str, name: str, offset: float = 0.0) -> list[dict]:
    """The rectangles of wall ``w`` (height ``h``) around its openings, ``offset`` into the room."""
    cuts = sorted({0.0, w.length, *[o.s0 for o in w.openings], *[o.s1 for o in w.openings]})
    n3 = (w.normal[0], 0.0, w.normal[1])
    pieces = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b - a < 1e-6:
            continue
        holes = [o for o in w.openings if o.s0 <= a + 1e-9 and o.s1 >= b - 1e-9]
        spans = [(0.0, h)] if not holes else [(0.0, holes[0].y0), (holes[0].y1, h)]
        for y0, y1 in spans:
            if y1 - y0 < 1e-6:
                continue
            mid = w.point((a + b) / 2, offset)
            pieces.append(rect(f"{name}_{len(pieces)}", material, (mid[0], (y0 + y1) / 2, mid[1]), n3,
                               (0, 1, 0), (b - a, y1 - y0)))
    return pieces
