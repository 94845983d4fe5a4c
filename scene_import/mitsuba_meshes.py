"""Mitsuba XML, the mesh files: ``obj``/``ply`` are copied beside the scene; ``serialized`` (Mitsuba's
zlib-compressed mesh container, one or more meshes per file, picked by ``shape_index``) is read
(:func:`read_serialized`) and written as binary PLY (positions, and normals/UVs when the mesh has
them), since the scene format takes OBJ and PLY only. A mesh flagged for face normals is shaded flat
(``face_normals``); one without normals gets smooth ones from the renderer, as in Mitsuba.
"""

from __future__ import annotations

import shutil
import struct
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import numpy as np

from illumix.scene.spectra import SceneError
from illumix.scene_import.mitsuba_xml_values import XmlDoc

MESHES = ("obj", "ply", "serialized")


def mesh_doc(d: XmlDoc, el: ET.Element, t: str, name: str, what: str) -> dict | None:
    """The shape document fields of a mesh shape (``type``, ``filename``, ``face_normals``), or None
    (with a warning) when its file is missing or unreadable."""
    b = d.b
    src = d.file(el, d.value(el, "filename", "") or "")
    if not src.is_file():
        b.warn(f"{what}: mesh file {src.name!r} does not exist; skipped")
        return None
    face_normals = bool(d.value(el, "face_normals", False))
    if t != "serialized":
        path, rel = b.file_path(src.stem, src.suffix.lower())
        shutil.copyfile(src, path)
        return {"type": t, "filename": rel, "face_normals": face_normals}
    index = int(d.value(el, "shape_index", 0))
    pos, faces, normals, uv, flat = read_serialized(src, index)
    rel = b.write_ply(f"{name}", pos, faces, normals, uv)
    return {"type": "ply", "filename": rel, "face_normals": face_normals or flat}


SERIALIZED_ID = 0x041C  # the format identifier every mesh record starts with
HAS_NORMALS, HAS_UV, HAS_COLOURS, FACE_NORMALS, SINGLE, DOUBLE = 0x1, 0x2, 0x8, 0x10, 0x1000, 0x2000


def read_serialized(path, index: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, bool]:
    """``(positions (n, 3), faces (m, 3), normals (n, 3) or None, uv (n, 2) or None, face normals)`` of mesh ``index``
    of a ``.serialized`` file, in object space (Mitsuba's ``SerializedMesh`` format, versions 3 and 4:
    per mesh ``uint16 0x041C, uint16 version`` then a zlib stream of ``uint32 flags``, the name (v4,
    NUL-terminated), ``uint64`` vertex and face counts, positions, normals, UVs, colours (float32, or
    float64 with flag 0x2000) and ``uint32`` indices (``uint64`` past 2³² vertices); a file of several
    meshes ends with their offsets (``uint64``, v3: ``uint32``) and a ``uint32`` count). Read here with
    zlib and numpy: only the renderer package loads Mitsuba."""
    data = Path(path).read_bytes()
    bad = f"{path}: not a Mitsuba serialized mesh file"
    if len(data) < 8 or struct.unpack_from("<H", data)[0] != SERIALIZED_ID:
        raise SceneError(f"{bad} (no 0x041C header)")
    version = struct.unpack_from("<H", data, 2)[0]
    if version not in (3, 4):
        raise SceneError(f"{bad} (format version {version}; 3 and 4 are read)")
    offset = 0
    if index:
        count = struct.unpack_from("<I", data, len(data) - 4)[0]
        if not 0 <= index < count:
            raise SceneError(f"{path}: cannot read mesh {index} of this serialized file (it holds {count}); "
                             f"give shape_index 0..{count - 1}")
        width = 8 if version == 4 else 4
        offset = struct.unpack_from("<Q" if width == 8 else "<I", data, len(data) - 4 - width * (count - index))[0]
    try:
        raw = zlib.decompressobj().decompress(data[offset + 4:])
    except zlib.error as exc:
        raise SceneError(f"{bad} (mesh {index}: {exc})") from None
    flags = struct.unpack_from("<I", raw)[0]
    pos = 4
    if version == 4:
        pos = raw.index(b"\0", pos) + 1
    n, m = struct.unpack_from("<QQ", raw, pos)
    pos += 16
    real = np.dtype("<f8" if flags & DOUBLE else "<f4")

    def take(dtype, count: int) -> np.ndarray:
        nonlocal pos
        a = np.frombuffer(raw, dtype=dtype, count=count, offset=pos)
        pos += a.nbytes
        return a

    xyz = take(real, 3 * n).reshape(n, 3)
    normals = take(real, 3 * n).reshape(n, 3) if flags & HAS_NORMALS else None
    uv = take(real, 2 * n).reshape(n, 2) if flags & HAS_UV else None
    if flags & HAS_COLOURS:
        take(real, 3 * n)  # vertex colours: illumix materials do not use them
    faces = take(np.dtype("<u8" if n > 0xFFFFFFFF else "<u4"), 3 * m).reshape(m, 3)
    if m and int(faces.max()) >= n:
        raise SceneError(f"{bad} (mesh {index}: a face indexes vertex {int(faces.max())} of {n})")
    return xyz.astype(np.float32), faces.astype(np.int64), normals, uv, bool(flags & FACE_NORMALS)


def object_points(b, doc: dict) -> np.ndarray:
    """Object-space points ``(k, 3)`` whose bounding box holds the shape ``doc`` (for the default view's
    framing): the canonical primitives' corners, a sphere's or cylinder's box, a mesh file's bounds
    (read with trimesh; the origin when it cannot be read)."""
    t = doc["type"]
    box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    if t in ("rectangle", "disk"):
        return box * [1, 1, 0]
    if t == "cube":
        return box
    if t == "sphere":
        return np.asarray(doc["center"], float) + box * float(doc["radius"])
    if t == "cylinder":
        r = float(doc["radius"])
        return np.vstack([np.asarray(doc["p0"], float) + box * r, np.asarray(doc["p1"], float) + box * r])
    try:
        import trimesh

        lo, hi = np.asarray(trimesh.load(b.out_dir / doc["filename"], process=False, force="mesh").bounds, float)
        return lo + (box + 1) / 2 * (hi - lo)
    except (ImportError, ValueError, OSError, IndexError, AttributeError):
        return np.zeros((1, 3))
