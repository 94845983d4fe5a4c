"""Parts: what a built item is (:class:`Item`), the primitive shapes the room shell and the emitters
are made of (furniture and clutter are triangle meshes: :mod:`scenegen.mesh`,
:mod:`scenegen.meshparts`), and how a built item is placed in a room.

An :class:`Item` is described in its own frame: origin at the centre of its footprint on the floor
(``y = 0`` is what it stands on), its front facing ``+z``, ``x`` to its right. Its ``shapes`` are scene
shape documents (:mod:`scene.schema`) in that frame; :func:`place` turns them by a
multiple of 90° about ``y`` and moves them into the room. Materials are names handed out by a
:class:`MaterialPicker` (:mod:`scenegen.materials`), so an item never defines materials itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from illumix.scene.demo import frame_matrix


class MaterialPicker(Protocol):
    """Hands out material names of a scene by class, defining them on first use."""

    def pick(self, cls: str) -> str:
        """A material of class ``cls`` (see :data:`scenegen.materials.CLASSES`), new or reused."""


@dataclass
class Surface:
    """A horizontal, free top surface clutter may stand on: height ``y`` (m), centre ``(x, z)`` and
    size ``(w, d)`` (m) in the item's frame."""

    y: float
    center: tuple[float, float]
    size: tuple[float, float]


@dataclass
class Item:
    """A built piece of furniture or clutter (see module docstring)."""

    kind: str
    shapes: list[dict]
    footprint: tuple[float, float]  # (width along x, depth along z), metres
    height: float
    surfaces: list[Surface] = field(default_factory=list)
    against_wall: bool = False  # stands with its back (-z side) to a wall


def _m(a) -> list[list[float]]:
    return np.asarray(a, dtype=float).round(9).tolist()


def box(name: str, material: str, center, half) -> dict:
    """An axis-aligned box (Mitsuba ``cube``) with centre and half extents (m)."""
    m = np.diag([*half, 1.0])
    m[:3, 3] = center
    return {"name": name, "type": "cube", "material": material, "transform": {"matrix": _m(m)}}


def cylinder(name: str, material: str, p0, p1, radius: float) -> dict:
    """An open cylinder between ``p0`` and ``p1`` (cap it with :func:`disk`)."""
    return {"name": name, "type": "cylinder", "material": material, "p0": [float(v) for v in p0],
            "p1": [float(v) for v in p1], "radius": float(radius)}


def sphere(name: str, material: str, center, radius: float) -> dict:
    return {"name": name, "type": "sphere", "material": material, "center": [float(v) for v in center],
            "radius": float(radius)}


def rect(name: str, material: str | None, center, normal, up, size, emitter: dict | None = None) -> dict:
    """A rectangle ``size = (w, h)`` facing ``normal`` with local +v along ``up``; optional area emitter."""
    d = {"name": name, "type": "rectangle", "transform": {"matrix": frame_matrix(center, normal, up, size)}}
    if material is not None:
        d["material"] = material
    if emitter is not None:
        d["emitter"] = emitter
    return d


def disk(name: str, material: str | None, center, normal, radius: float, emitter: dict | None = None) -> dict:
    up = (0, 0, 1) if abs(normal[1]) > 0.9 else (0, 1, 0)
    d = {"name": name, "type": "disk", "transform": {"matrix": frame_matrix(center, normal, up, (2 * radius,) * 2)}}
    if material is not None:
        d["material"] = material
    if emitter is not None:
        d["emitter"] = emitter
    return d


def rotation_y(quarter_turns: int) -> np.ndarray:
    """4×4 rotation about +y by ``quarter_turns`` × 90° (exact entries)."""
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][quarter_turns % 4]
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]], dtype=float)


def transform_shape(d: dict, m: np.ndarray, prefix: str = "") -> dict:
    """A copy of shape document ``d`` moved by the 4×4 matrix ``m`` (a rigid motion), renamed
    ``prefix + name``."""
    out = dict(d)
    out["name"] = prefix + d["name"]
    if d["type"] == "sphere":
        out["center"] = list((m @ [*d["center"], 1.0])[:3].round(9))
    elif d["type"] == "cylinder":
        out["p0"] = list((m @ [*d["p0"], 1.0])[:3].round(9))
        out["p1"] = list((m @ [*d["p1"], 1.0])[:3].round(9))
    if "transform" in d:
        out["transform"] = {"matrix": _m(m @ np.asarray(d["transform"]["matrix"], dtype=float))}
    return out


def place(item: Item, x: float, z: float, quarter_turns: int, prefix: str, y: float = 0.0) -> list[dict]:
    """The item's shapes in the room: turned by ``quarter_turns`` × 90° about y, its footprint centre
    moved to ``(x, y, z)``, every name prefixed."""
    m = rotation_y(quarter_turns)
    m[:3, 3] = (x, y, z)
    return [transform_shape(s, m, prefix) for s in item.shapes]


def footprint_extent(item: Item, quarter_turns: int) -> tuple[float, float]:
    """The ``(x, z)`` extent of the item's footprint after turning it."""
    w, d = item.footprint
    return (d, w) if quarter_turns % 2 else (w, d)


def deg(a: float) -> float:
    return math.radians(a)
