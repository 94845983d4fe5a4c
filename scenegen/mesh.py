"""Triangle meshes for generated objects: bevelled and rounded boxes, extruded 2D profiles, lathed
(revolved) profiles, rectangular frames swept from a cross-section, leaves and sheets.

Every builder returns a :class:`Mesh` in metres — positions ``(n, 3)``, triangles ``(m, 3)``
(counter-clockwise seen from outside) and shading normals ``(n, 3)`` — closed (watertight once
coincident vertices are merged) unless its docstring says otherwise. Solids are exact where they can
be (a rounded box's normals are analytic; a lathe is split into smooth bands at its sharp profile
corners, so rims and bottoms stay crisp). :mod:`scenegen.meshparts` turns them into PLY files with
texture coordinates in metres.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Mesh:
    """Positions ``v`` (n, 3) float64 m, triangles ``f`` (m, 3) int64, unit normals ``n`` (n, 3)."""

    v: np.ndarray
    f: np.ndarray
    n: np.ndarray

    def moved(self, m: np.ndarray) -> Mesh:
        """The mesh through the 4×4 matrix ``m`` (rotation/scale + translation; normals by the inverse
        transpose, faces flipped when ``m`` mirrors)."""
        a = np.asarray(m, float)[:3, :3]
        v = self.v @ a.T + np.asarray(m, float)[:3, 3]
        n = self.n @ np.linalg.inv(a)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        f = self.f[:, ::-1] if np.linalg.det(a) < 0 else self.f
        return Mesh(v, f.copy(), n)

    def at(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Mesh:
        return Mesh(self.v + (x, y, z), self.f, self.n)

    def face_normals(self) -> np.ndarray:
        p = self.v[self.f]
        c = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        return c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-20)

    def volume(self) -> float:
        p = self.v[self.f]
        return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6)


def concat(meshes: list[Mesh]) -> Mesh:
    """One mesh of several (indices shifted)."""
    off = np.cumsum([0] + [len(m.v) for m in meshes[:-1]])
    return Mesh(np.concatenate([m.v for m in meshes]), np.concatenate([m.f + o for m, o in zip(meshes, off)]),
                np.concatenate([m.n for m in meshes]))


def flat(v: np.ndarray, f: np.ndarray) -> Mesh:
    """Flat shading: every triangle its own three vertices with the face normal."""
    v, f = np.asarray(v, float), np.asarray(f, np.int64)
    m = Mesh(v, f, np.zeros_like(v))
    fn = m.face_normals()
    return Mesh(v[f].reshape(-1, 3), np.arange(3 * len(f)).reshape(-1, 3), np.repeat(fn, 3, axis=0))


def smooth(v: np.ndarray, f: np.ndarray) -> Mesh:
    """Smooth shading: area-weighted vertex normals."""
    v, f = np.asarray(v, float), np.asarray(f, np.int64)
    p = v[f]
    c = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], c)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
    return Mesh(v, f, n)


def _edge_coords(h: float, r: float, k: int) -> np.ndarray:
    """Grid coordinates along one axis of a rounded box: ``k`` steps around each rounded edge."""
    if r <= 0 or k == 0:
        return np.array([-h, h])
    t = np.linspace(0, math.pi / 2, k + 1)
    a = -h + r * (1 - np.cos(t))
    return np.concatenate([a, -a[::-1]])


@functools.lru_cache(maxsize=8)
def _box_template(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The topology of a box whose faces are ``(n − 1)²`` quad grids: per vertex the axis its face is
    fixed on, that face's sign, and for every axis the grid index along it (``(V, 3)``; unused on the
    fixed axis); the triangles, counter-clockwise seen from outside."""
    fixed, signs, idx, faces, base = [], [], [], [], 0
    for ax in range(3):
        u, w = [a for a in range(3) if a != ax]
        for sign in (-1.0, 1.0):
            iu, iw = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
            ii = np.zeros((n * n, 3), np.int64)
            ii[:, u], ii[:, w] = iu.ravel(), iw.ravel()
            grid = base + np.arange(n * n).reshape(n, n)
            q = np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], -1).reshape(-1, 4)
            tri = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
            # quads run +u then +w: their normal is e_u × e_w (−y for the y faces, +x, +z otherwise)
            faces.append(tri[:, ::-1] if sign != (-1.0 if ax == 1 else 1.0) else tri)
            fixed.append(np.full(n * n, ax))
            signs.append(np.full(n * n, sign))
            idx.append(ii)
            base += n * n
    return np.concatenate(fixed), np.concatenate(signs), np.concatenate(idx), np.concatenate(faces)


def rounded_box(half, r: float = 0.004, k: int = 2, bulge: float = 0.0) -> Mesh:
    """A box of half extents ``half`` (m) centred at the origin, edges and corners rounded with radius
    ``r`` (``k`` segments per quarter circle); ``bulge`` (m) puffs the top and bottom faces up/down at
    their centre (cushions, mattresses). Analytic normals."""
    half = np.asarray(half, float)
    r = float(min(r, 0.999 * half.min()))
    if r <= 0:
        k = 0
    axes = np.stack([_edge_coords(h, r, k) for h in half])  # (3, n)
    fixed, sign, idx, f = _box_template(axes.shape[1])
    v = axes[np.arange(3)[None, :], idx]
    at = fixed[:, None] == np.arange(3)[None, :]
    v = np.where(at, sign[:, None] * half[None, :], v)
    if k == 0:  # a plain box: flat shading (grid vertices of different faces differ anyway)
        return flat(v, f)
    inner = half - r
    c = np.clip(v, -inner, inner)
    d = v - c
    n = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-20)
    v = c + r * n
    if bulge:
        s = np.clip(1 - (v[:, 0] / half[0]) ** 2, 0, 1) * np.clip(1 - (v[:, 2] / half[2]) ** 2, 0, 1)
        v[:, 1] += np.sign(v[:, 1]) * bulge * s
        return smooth(v, f)
    return Mesh(v, f, n)


def box(center, half) -> Mesh:
    """A plain box (flat shading) — for thin parts where a bevel would not show."""
    return rounded_box(half, 0.0, 0).at(*center)


def bevel_box(center, half, r: float = 0.003) -> Mesh:
    """A box with bevelled (rounded, ``r`` m) edges: what turned furniture edges look like."""
    return rounded_box(half, r, 2).at(*center)


def _left(e0, e1, pts: np.ndarray) -> np.ndarray:
    """> 0 where ``pts`` lie left of the edge ``e0 → e1`` (inside a counter-clockwise triangle)."""
    return (e1[0] - e0[0]) * (pts[:, 1] - e0[1]) - (e1[1] - e0[1]) * (pts[:, 0] - e0[0])


def triangulate(poly) -> np.ndarray:
    """Ear clipping of a simple polygon ``(n, 2)`` (either winding): triangles ``(n − 2, 3)`` as
    indices, counter-clockwise."""
    p = np.asarray(poly, float)
    area = 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
    idx = list(range(len(p))) if area > 0 else list(range(len(p)))[::-1]
    tris = []
    while len(idx) > 3:
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = p[i0], p[i1], p[i2]
            if (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]) <= 1e-14:
                continue  # reflex or flat corner
            rest = p[[j for j in idx if j not in (i0, i1, i2)]]
            if len(rest) and np.any((_left(a, b, rest) >= 0) & (_left(b, c, rest) >= 0) & (_left(c, a, rest) >= 0)):
                continue
            tris.append((i0, i1, i2))
            idx.pop(k)
            break
        else:
            raise ValueError("triangulate: the polygon is not simple (self-intersecting or degenerate)")
    tris.append(tuple(idx))
    return np.asarray(tris, np.int64)


def extrude(poly, z0: float, z1: float, smooth_sides: bool = False) -> Mesh:
    """The prism of polygon ``poly`` ``(n, 2)`` (x, y) between ``z0`` and ``z1``: flat caps, sides flat
    or (``smooth_sides``: curtains, rounded profiles) smooth around the outline."""
    p = np.asarray(poly, float)
    area = 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
    if area < 0:
        p = p[::-1]
    n = len(p)
    tri = triangulate(p)
    bot = np.c_[p, np.full(n, z0)]
    top = np.c_[p, np.full(n, z1)]
    caps = concat([flat(top, tri), flat(bot, tri[:, ::-1])])
    i = np.arange(n)
    j = (i + 1) % n
    v = np.concatenate([bot, top])
    f = np.concatenate([np.c_[i, j, j + n], np.c_[i, j + n, i + n]])
    sides = smooth(v, f) if smooth_sides else flat(v, f)
    return concat([caps, sides])


def lathe(profile, segments: int = 24, sharp=()) -> Mesh:
    """The solid of revolution about +y of ``profile`` ``(n, 2)`` = (radius, y) points from the axis
    at the bottom round to the axis at the top (first and last radius 0 for a closed solid). Split
    into smoothly shaded bands at the profile indices in ``sharp`` (rims, bottom edges)."""
    p = np.asarray(profile, float)
    cuts = sorted({0, len(p) - 1, *[int(s) for s in sharp]})
    th = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    cs, sn = np.cos(th), np.sin(th)
    bands = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        q = p[a:b + 1]
        v = np.stack([q[:, :1] * cs, np.repeat(q[:, 1:2], segments, 1), q[:, :1] * sn], -1).reshape(-1, 3)
        i = np.arange(len(q) - 1)[:, None] * segments
        s0, s1 = np.arange(segments)[None, :], (np.arange(segments)[None, :] + 1) % segments
        a0, a1, b0, b1 = (i + s0).ravel(), (i + s1).ravel(), (i + segments + s0).ravel(), (i + segments + s1).ravel()
        f = np.concatenate([np.c_[a0, b0, b1], np.c_[a0, b1, a1]])
        pv = v[f]  # drop triangles collapsed at the axis
        keep = np.linalg.norm(np.cross(pv[:, 1] - pv[:, 0], pv[:, 2] - pv[:, 0]), axis=1) > 1e-14
        bands.append(smooth(v, f[keep]))
    m = concat(bands)
    if m.volume() < 0:
        m = Mesh(m.v, m.f[:, ::-1].copy(), m.n)
    # normals of vertices on the axis: straight up or down
    on_axis = np.hypot(m.v[:, 0], m.v[:, 2]) < 1e-12
    m.n[on_axis] = np.sign(m.n[on_axis, 1:2] + 1e-30) * np.array([0.0, 1.0, 0.0])
    return m


def rod(p0, p1, r: float, segments: int = 12) -> Mesh:
    """A closed cylinder from ``p0`` to ``p1`` (m), radius ``r``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    length = float(np.linalg.norm(p1 - p0))
    m = lathe([(0, 0), (r, 0), (r, length), (0, length)], segments, sharp=(1, 2))
    y = (p1 - p0) / length
    x = np.cross(y, [0, 0, 1.0]) if abs(y[2]) < 0.9 else np.cross(y, [1.0, 0, 0])
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    t = np.eye(4)
    t[:3, :3] = np.stack([x, y, z], 1)
    t[:3, 3] = p0
    return m.moved(t)


def frame_ring(w: float, h: float, section) -> Mesh:
    """A rectangular frame (picture frame, architrave, door frame) in the xy plane, centred at the
    origin: the closed cross-section ``section`` ``(k, 2)`` = (outward offset from the inner
    ``w × h`` opening, z) swept around it with mitred corners. Flat shading."""
    s = np.asarray(section, float)
    corners = np.array([(-w / 2, -h / 2, -1, -1), (w / 2, -h / 2, 1, -1), (w / 2, h / 2, 1, 1), (-w / 2, h / 2, -1, 1)])
    k = len(s)
    v = np.array([(cx + sx * o, cy + sy * o, z) for o, z in s for cx, cy, sx, sy in corners])
    i = np.arange(k)[:, None] * 4
    c0, c1 = np.arange(4)[None, :], (np.arange(4)[None, :] + 1) % 4
    a0, a1 = (i + c0).ravel(), (i + c1).ravel()
    b0, b1 = ((i + 4) % (4 * k) + c0).ravel(), ((i + 4) % (4 * k) + c1).ravel()
    f = np.concatenate([np.c_[a0, a1, b1], np.c_[a0, b1, b0]])
    m = flat(v, f)
    if m.volume() < 0:
        m = flat(v, f[:, ::-1])
    return m


def leaf(length: float, width: float, droop: float, segments: int = 6) -> Mesh:
    """An open leaf blade along +x from the origin: elliptic outline, folded along the midrib, bending
    down by ``droop`` (m) at the tip. A two-sided sheet (not closed)."""
    t = np.linspace(0, 1, segments + 1)
    half = width / 2 * np.sin(np.pi * np.clip(t, 0, 1)) ** 0.7
    y = -droop * t ** 2
    rows = []
    for s in (-1.0, 0.0, 1.0):
        rows.append(np.c_[t * length, y + (0.15 * width if s == 0 else 0.0), s * half])
    v = np.concatenate(rows)
    n1 = segments + 1
    i = np.arange(segments)
    f = []
    for r in range(2):
        a, b = r * n1 + i, (r + 1) * n1 + i
        f += [np.c_[a, b, b + 1], np.c_[a, b + 1, a + 1]]
    f = np.concatenate(f)
    pv = v[f]
    keep = np.linalg.norm(np.cross(pv[:, 1] - pv[:, 0], pv[:, 2] - pv[:, 0]), axis=1) > 1e-14
    return smooth(v, f[keep])


def rotate_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def rotate_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def rotate_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


SIDE = np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]])
"""Maps an extrusion built in the xy plane along z to one built in the zy plane along x (a side
profile — chair sides, sofa arms — extruded across the width)."""
