"""The scene document an importer assembles: named materials, shapes, lights, views, the mesh and
image files beside it, and the light groups (:mod:`scene_import.rules`, :mod:`scene_import.colour_match`).

Importers call :class:`SceneBuilder` with plain data; :meth:`SceneBuilder.finish` returns the
document (a dict for :func:`scene.load.scene_from_dict`). Files go under
``out_dir/assets`` and are referenced relative to ``out_dir``, where the scene file is written.

Conventions: metres, right-handed, +y up (glTF's and illumix's frame; other frames are the
importer's business). Meshes are written as binary little-endian PLY with per-vertex normals and
UVs in Mitsuba's bitmap convention (``(0, 0)`` is the image's top-left texel, as in glTF; OBJ's
``vt`` has v up and is flipped by the OBJ importer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from illumix.scene.spectra import SceneError
from illumix.scene_import.grouping import Emitter, assign, group_emission
from illumix.scene_import.names import Names, key_name, renamed_summary
from illumix.scene_import.rules import Rules

DEFAULT_WIDTH = 320  # pixels of an imported view (views carry no resolution in glTF/OBJ)


@dataclass
class SceneBuilder:
    out_dir: Path
    assets: str
    source: Path
    fmt: str
    warnings: list[str] = field(default_factory=list)
    materials: dict[str, dict] = field(default_factory=dict)
    shapes: list[dict] = field(default_factory=list)
    lights: list[dict] = field(default_factory=list)
    views: list[dict] = field(default_factory=list)
    emitters: list[Emitter] = field(default_factory=list)
    max_depth: int | None = None
    lo: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    hi: np.ndarray = field(default_factory=lambda: np.full(3, -np.inf))

    def __post_init__(self) -> None:
        # renderer-safe unique keys per kind (scene_import.names): "Cube.001" → "Cube_001"
        self._shape_names, self._light_names, self._view_names = Names(), Names(), Names()
        self._mat_names, self._files, self._group_names = Names(), Names(), Names()

    # -- bookkeeping ------------------------------------------------------------------------------

    def warn(self, msg: str) -> None:
        if msg not in self.warnings:
            self.warnings.append(msg)

    def add_material(self, name: str, doc: dict) -> str:
        key = self._mat_names(name, "material")
        self.materials[key] = doc
        return key

    def file_path(self, name: str, suffix: str) -> tuple[Path, str]:
        """``(absolute path, path relative to out_dir)`` of a new asset file."""
        # the name as given, less a file extension it may carry: Path.stem would cut "Cube.001-0" at ".001-0"
        base = name[: -len(suffix)] if suffix and name.lower().endswith(suffix.lower()) else name
        stem = self._files(Path(base).name or "file", "file")
        rel = f"{self.assets}/{stem}{suffix}"
        path = self.out_dir / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        return path, rel

    def extend_bounds(self, points: np.ndarray) -> None:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        p = p[np.all(np.isfinite(p), axis=1)]
        if p.size:
            self.lo = np.minimum(self.lo, p.min(axis=0))
            self.hi = np.maximum(self.hi, p.max(axis=0))

    # -- geometry -----------------------------------------------------------------------------------

    def write_ply(self, name: str, positions, faces, normals=None, uv=None) -> str:
        """Write a triangle mesh (object space) as binary PLY; returns its path relative to ``out_dir``."""
        v = np.asarray(positions, dtype="<f4").reshape(-1, 3)
        f = np.asarray(faces, dtype="<i4").reshape(-1, 3)
        cols, props = [v], ["x", "y", "z"]
        if normals is not None:
            cols.append(np.asarray(normals, dtype="<f4").reshape(-1, 3))
            props += ["nx", "ny", "nz"]
        if uv is not None:
            cols.append(np.asarray(uv, dtype="<f4").reshape(-1, 2))
            props += ["u", "v"]
        path, rel = self.file_path(name, ".ply")
        header = ["ply", "format binary_little_endian 1.0", "comment illumix import", f"element vertex {len(v)}",
                  *[f"property float {p}" for p in props], f"element face {len(f)}",
                  "property list uchar int vertex_indices", "end_header"]
        face_rec = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
        face_rec["n"], face_rec["i"] = 3, f
        with open(path, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii"))
            fh.write(np.ascontiguousarray(np.hstack(cols), dtype="<f4").tobytes())
            fh.write(face_rec.tobytes())
        return rel

    def add_shape(self, name: str, doc: dict, emitter: tuple[list[str], str, np.ndarray | None, float] | None = None,
                  what: str = "", *, spectrum: dict | str | None = None, given: str = "") -> dict:
        """Add a shape document (``type`` and its fields, ``material`` and/or ``transform``);
        ``emitter``: ``(names, own group key, xy, strength)`` makes it an area light; ``spectrum`` /
        ``given``: its exact emission and how the file gave it (:class:`scene_import.grouping.Emitter`)."""
        d = {"name": self._shape_names(name, "shape"), **doc}
        if emitter is not None:
            names, key, xy, strength = emitter
            d["emitter"] = {"group": None, "strength": float(strength)}
            self.emitters.append(Emitter(d, [*names, d["name"]], key, xy, what or f"shape {name!r}", spectrum, given))
        if "material" not in d and "emitter" not in d:
            raise ValueError("a shape needs a material or an emitter")
        self.shapes.append(d)
        return d

    def add_light(self, name: str, doc: dict, xy: np.ndarray | None, strength: float,
                  names: list[str] | None = None, what: str = "", *, spectrum: dict | str | None = None,
                  given: str = "") -> dict:
        for key in ("position", "direction"):
            v = np.asarray(doc.get(key, (0.0, 0.0, 1.0)), dtype=float)
            if not np.all(np.isfinite(v)) or (key == "direction" and np.linalg.norm(v) < 1e-12):
                raise SceneError(f"{what or f'light {name!r}'}: its {key} is degenerate (zero scale?); "
                                 "fix the light in the source file")
        d = {"name": self._light_names(name, "light"), **doc, "group": None, "strength": float(strength)}
        self.emitters.append(Emitter(d, [*(names or [name]), d["name"]], name, xy, what or f"light {name!r}",
                                     spectrum, given))
        self.lights.append(d)
        return d

    def add_view(self, name: str, origin, forward, up, fov: float, resolution: tuple[int, int]) -> None:
        """A view from a camera frame: ``forward``/``up`` world directions, ``fov`` horizontal (degrees)."""
        o, f, u = (np.asarray(a, dtype=float) for a in (origin, forward, up))
        what = f"camera {name!r}"
        if not (np.all(np.isfinite(o)) and np.all(np.isfinite(f)) and np.linalg.norm(f) > 1e-12):
            raise SceneError(f"{what}: its position or direction is degenerate (zero scale or target at the "
                             "origin); fix the camera in the source file")
        f = f / np.linalg.norm(f)
        if not np.all(np.isfinite(u)) or np.linalg.norm(np.cross(f, u)) < 1e-9 * max(np.linalg.norm(u), 1e-300):
            # looking straight along its up (a top-down lookat with up +y): any perpendicular up frames it
            u = np.array([0.0, 0.0, -1.0]) if abs(f[1]) > 0.9 else np.array([0.0, 1.0, 0.0])
            self.warn(f"{what}: its up vector is parallel to its view direction; used {_r(u)}")
        u = u / np.linalg.norm(u)
        self.views.append({"name": self._view_names(name, "view"), "origin": _r(o), "target": _r(o + f),
                           "up": _r(u), "fov": round(float(fov), 6), "resolution": [int(resolution[0]),
                                                                                    int(resolution[1])]})

    def default_view(self, why: str) -> None:
        """A view framing the scene's bounding box from the front (+z), slightly above (60° fov, 4:3)."""
        lo, hi = (self.lo, self.hi) if np.all(np.isfinite(self.lo)) else (np.full(3, -1.0), np.ones(3))
        c, r = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
        fov, w, h = 60.0, DEFAULT_WIDTH, DEFAULT_WIDTH * 3 // 4
        vfov = 2 * math.atan(math.tan(math.radians(fov) / 2) * h / w)
        d = np.array([0.0, 0.35, 1.0]) / np.linalg.norm([0.0, 0.35, 1.0])
        origin = c + d * (r / math.sin(vfov / 2)) * 1.05
        self.add_view("default", origin, c - origin, [0.0, 1.0, 0.0], fov, (w, h))
        self.warn(f"{why}: added a view 'default' framing the scene's bounding box from +z "
                  f"(origin {_r(origin)}, fov 60°)")

    # -- the document -------------------------------------------------------------------------------

    def finish(self, name: str, rules: Rules | None, description: str = "", sky: bool = False) -> dict:
        """The scene document: light groups assigned (:func:`scene_import.grouping.assign`) and their
        spectra chosen (:func:`scene_import.grouping.group_emission`); renamed names recorded.

        Nothing renderable is a :class:`SceneError`: no shape, or no emitter unless ``sky`` (then a
        constant D65 sky of radiance 1 lights it, with a warning)."""
        skipped = f" ({len(self.warnings)} warning(s): {self.warnings[0][:160]} …)" if self.warnings else ""
        if not self.shapes:
            raise SceneError(f"{self.source}: nothing to render: no shape could be imported{skipped}")
        if not self.emitters and not sky:
            raise SceneError(f"{self.source}: nothing to render: nothing emits light (no light or emitting "
                             f"material could be imported); add one, or light it with a constant sky: illumix import --sky")
        if not self.emitters:
            self.add_light("sky", {"type": "constant"}, None, 1.0, what="default sky")
            self.warn(f"{self.source.name}: nothing emits light; added a constant sky 'sky' of radiance 1 (D65)")
        if not self.views:
            self.default_view(f"{self.source.name}: no camera")
        members = assign(self.emitters, rules, self._group_names)
        if rules:
            for r in rules.groups:
                if r.name not in members:
                    self.warn(f"rules: group {r.name!r} matches no light or emissive material "
                              f"(patterns {', '.join(r.match)})")
        light_groups = []
        for g, es in members.items():
            emission, how = group_emission(g, es, rules.illuminant(g) if rules else None, self.warn)
            for e in es:
                e.set_group(g)
            desc = (rules.description(g) if rules else "") or (
                f"imported: {', '.join(dict.fromkeys(n for e in es for n in e.names[:1]))} ({how})")
            group = {"name": g, "emission": emission, "description": desc[:300]}
            kinds = {"daylight" if e.type in ("envmap", "constant", "directional") else "artificial" for e in es}
            if len(kinds) == 1:
                group["kind"] = kinds.pop()
            light_groups.append(group)
        generator = {"name": "illumix.import", "format": self.fmt, "file": self.source.name}
        renamed, n = renamed_summary({"shape": self._shape_names, "light": self._light_names,
                                      "material": self._mat_names, "view": self._view_names})
        if n:
            generator["renamed"] = renamed  # the source file's names, for finding objects again
            first = renamed.split(";")[0].split(": ", 1)[1]
            self.warn(f"{self.source.name}: {n} name(s) changed to renderer-safe keys (e.g. {first}); "
                      "the originals are listed in the scene's generator.renamed")
        doc = {"name": key_name(name, "imported"), "description": description, "generator": generator,
               "materials": self.materials, "shapes": self.shapes, "lights": self.lights,
               "light_groups": light_groups, "views": self.views}
        if self.max_depth is not None:
            doc["max_depth"] = self.max_depth
        return _plain(doc)


def _plain(x):
    """The document with numpy scalars and arrays as plain Python (YAML/JSON writable)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def _r(v) -> list[float]:
    return [round(float(x), 9) for x in v]
