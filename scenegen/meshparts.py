"""Meshes into scene shapes: the parts of one item, grouped by material, written as binary PLY files
with texture coordinates in metres.

:class:`Parts` collects :class:`scenegen.mesh.Mesh` parts of an item in its own frame
(:mod:`scenegen.parts`) with their material names; :meth:`Parts.shapes` merges the parts of each
material into one mesh and returns ``ply`` shape documents (identity ``transform``, so
:func:`scenegen.parts.place` moves them like any other shape).

**Texture coordinates.** Every triangle is box-projected onto the plane its normal is closest to
(x faces take (z, y), y faces (x, z), z faces (x, y)), in metres of the item's frame, so a pattern
texture's ``scale`` is repeats *per metre* on every mesh and a wood grain, weave or tile has the
same physical size on a chair leg as on a table top (:mod:`scenegen.materials` sets those scales). A
part may shift its UVs (``uv_offset``: planks and books cut from different parts of one texture) or
span ``[0, 1]`` over its own extent (``uv="unit"``: a rug's or a curtain's whole pattern).

**Files.** Little-endian binary PLY (float ``x y z nx ny nz u v``, ``uchar int`` triangle lists, as the
importers write them), named by the sha256 of their bytes under ``$ILLUMIX_CACHE/scenegen-meshes``
(default ``~/.cache/illumix``): the same item twice is one file, a file is written once (under a
temporary name, then renamed), and a room's document stays a function of its seed. Shape documents
carry the absolute path.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from illumix.scenegen.mesh import Mesh, concat

_IDENTITY = {"matrix": np.eye(4).tolist()}
_WRITTEN: dict[str, np.ndarray] = {}  # files this process has written or seen: their (2, 3) bounds


def mesh_dir() -> Path:
    """Where generated meshes are kept (see module docstring)."""
    root = Path(os.environ.get("ILLUMIX_CACHE", Path.home() / ".cache" / "illumix")).expanduser()
    return root / "scenegen-meshes"


def _project(m: Mesh, mode: str, offset: np.ndarray) -> tuple[Mesh, np.ndarray]:
    """Vertices split where the projection axis changes, and their ``(n, 2)`` UVs (module docstring);
    ``offset``: ``(2,)`` or one ``(2,)`` row per vertex of ``m``."""
    fn = m.face_normals()
    ax = np.argmax(np.abs(fn), axis=1)
    cls = ax * 2 + (fn[np.arange(len(fn)), ax] < 0)
    key = m.f * 6 + cls[:, None]
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    vi, vc = uniq // 6, uniq % 6
    v, n = m.v[vi], m.n[vi]
    axis = vc // 2
    pick = np.array([[2, 1], [0, 2], [0, 1]])[axis]  # (u, v) coordinates per projection axis
    uv = np.take_along_axis(v, pick, axis=1)
    mirror = np.where(vc % 2 == 1, -1.0, 1.0)  # keep the pattern un-mirrored on back faces
    uv[:, 0] *= np.where(axis == 1, 1.0, mirror)
    if mode == "unit":
        lo, hi = uv.min(axis=0), uv.max(axis=0)
        uv = (uv - lo) / np.maximum(hi - lo, 1e-9)
    off = np.asarray(offset, float)
    uv = uv + (off[vi] if off.ndim == 2 else off)
    return Mesh(v, inv.reshape(-1, 3), n), uv


def ply_bytes(m: Mesh, uv: np.ndarray) -> bytes:
    """A binary little-endian PLY of mesh ``m`` with ``uv`` (n, 2)."""
    head = ("ply\nformat binary_little_endian 1.0\ncomment illumix scenegen\n"
            f"element vertex {len(m.v)}\n" + "".join(f"property float {p}\n" for p in
                                                    ("x", "y", "z", "nx", "ny", "nz", "u", "v")) +
            f"element face {len(m.f)}\nproperty list uchar int vertex_indices\nend_header\n")
    verts = np.ascontiguousarray(np.hstack([m.v, m.n, uv]), dtype="<f4")
    rec = np.empty(len(m.f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"], rec["i"] = 3, m.f
    return head.encode("ascii") + verts.tobytes() + rec.tobytes()


def write_mesh(m: Mesh, uv: np.ndarray) -> str:
    """Write ``m`` (once) under :func:`mesh_dir`; its absolute path."""
    data = ply_bytes(m, uv)
    path = mesh_dir() / f"{hashlib.sha256(data).hexdigest()[:24]}.ply"
    key = str(path)
    if key not in _WRITTEN and not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, path)
    _WRITTEN[key] = np.array([m.v.min(axis=0), m.v.max(axis=0)])
    return key


def mesh_bounds(path: str) -> np.ndarray:
    """``(2, 3)`` bounds (m, the mesh's own frame) of a mesh file written here (read back otherwise)."""
    if path not in _WRITTEN:
        p = read_ply_positions(path)
        _WRITTEN[path] = np.array([p.min(axis=0), p.max(axis=0)])
    return _WRITTEN[path]


class Parts:
    """The meshes of one item by material (see module docstring)."""

    def __init__(self, name: str):
        self.name = name
        self.by_mat: dict[tuple[str, str], list[tuple[Mesh, str, tuple]]] = {}

    def add(self, material: str, mesh: Mesh, uv: str = "metric", uv_offset=(0.0, 0.0), apart: str = "") -> None:
        """Add a part; ``apart`` names a group kept out of the material's merged mesh (what stands
        on a top, e.g. a hob on a worktop: a shape of its own keeps its bounds its own)."""
        self.by_mat.setdefault((material, apart), []).append((mesh, uv, tuple(uv_offset)))

    def shapes(self) -> list[dict]:
        """One ``ply`` shape per material (and ``apart`` group), named ``{name}_mesh{k}``."""
        out = []
        for k, ((mat, _), parts) in enumerate(self.by_mat.items()):
            done = [_project(p[0], "unit", p[2]) for p in parts if p[1] == "unit"]  # each spans [0, 1]
            metric = [p for p in parts if p[1] != "unit"]
            if metric:  # projected at once, each part's offset on its vertices
                off = np.concatenate([np.tile(p[2], (len(p[0].v), 1)) for p in metric])
                done.append(_project(concat([p[0] for p in metric]), "metric", off))
            m = concat([d[0] for d in done])
            uv = np.concatenate([d[1] for d in done])
            out.append({"name": f"{self.name}_mesh{k}", "type": "ply", "filename": write_mesh(m, uv),
                        "material": mat, "transform": dict(_IDENTITY)})
        return out


def is_mesh(shape: dict) -> bool:
    return shape.get("type") in ("ply", "obj")


def read_ply_positions(path: str) -> np.ndarray:
    """The ``(n, 3)`` float64 vertex positions of a PLY written by :func:`ply_bytes`."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    n = int(data[:end].split(b"element vertex ")[1].split(b"\n")[0])
    return np.frombuffer(data, dtype="<f4", count=n * 8, offset=end).reshape(n, 8)[:, :3].astype(np.float64)


def mesh_area(path: str) -> float:
    """Surface area (m²) of a PLY written by :func:`ply_bytes` (its triangles, as written)."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end]
    n = int(head.split(b"element vertex ")[1].split(b"\n")[0])
    nf = int(head.split(b"element face ")[1].split(b"\n")[0])
    v = np.frombuffer(data, dtype="<f4", count=n * 8, offset=end).reshape(n, 8)[:, :3].astype(np.float64)
    rec = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=nf, offset=end + n * 32)
    p = v[rec["i"]]
    return float(np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum() / 2)
