"""Scene description, part 2: the whole :class:`Scene` — its parts (:mod:`scene.schema`)
cross-checked, looked up by name, resolved to spectra on the scene's grid, and hashed.

- **Cross-checks** name every broken reference (materials, light groups), duplicate names, a
  second sky, unknown conductors, emitter-less groups, a bad grid — all problems, one line.
- **Lookups**: groups (declared or by first use), views, the emitters of a group, portals.
- **Spectra** (:meth:`Scene.spectrum`, :meth:`Scene.emission`): band averages ``(n_bands,)`` float64
  on the scene grid from library, CSV, inline or constant specs (reflectances ≤ 1 checked).
- **Identity** (:meth:`Scene.content_hash`, :meth:`Scene.view_hash`): sha256 over everything a
  transport cube depends on, referenced files' bytes included — the store's ``scene_hash``.
"""

from __future__ import annotations

import hashlib
import json
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, PrivateAttr, model_validator

from illumix.scene.migrate import CURRENT
from illumix.scene.schema import (CONDUCTORS, ConstantSky, ConstantSpectrum, Dielectric,
                                        DirectionalLight, EnvMapSky, FileSpectrum, Light, LightGroup,
                                        LibrarySpectrum, Material, MeshFile, Name, RoughConductor, SceneError,
                                        Shape, SpectrumSpec, StrictModel, TableSpectrum, View)
from illumix.scene.textures import BitmapTexture, PatternTexture
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import SpectralGrid
from illumix.retarget.illuminants import illuminant_spd as _library_spd
from illumix.retarget.illuminants import spd_from_samples


#: Fields added to the format after scenes were first hashed, with the value that means "as before":
#: left out of :meth:`Scene.content_hash` at that value, so adding a field re-renders nothing.
ADDED_DEFAULTS = {"materials": {"normal_map": None}}


def _drop_added_defaults(doc: dict) -> None:
    """Remove :data:`ADDED_DEFAULTS` fields at their default from a scene dump (in place)."""
    for name, fields in ADDED_DEFAULTS.items():
        items = doc.get(name) or {}
        for item in (items.values() if isinstance(items, dict) else items):
            for field, default in fields.items():
                if isinstance(item, dict) and field in item and item[field] == default:
                    del item[field]


class GridSpec(StrictModel):
    """The spectral grid the scene is rendered on: band edges from ``start`` to ``end`` nm in ``step`` nm."""

    start: float = 395.0
    end: float = 705.0
    step: float = 5.0


class Scene(StrictModel):
    """A complete scene: see the module docstring."""

    name: Name = Field(description="the scene's name in the cube store (letters, digits, _ . + -)")
    schema_version: Literal[CURRENT] = Field(
        CURRENT, description=f"the scene format's version, {CURRENT}; files written in an older version are "
                             "migrated when loaded (scene.migrate), a document without it is read as version 1")
    description: str = ""
    grid: GridSpec = Field(GridSpec(), description="the spectral grid (nm) spectra are averaged onto")
    materials: dict[Name, Material] = Field(default_factory=dict, description="materials by name, each "
                                            "with measured or given reflectance spectra")
    shapes: list[Shape] = Field(default_factory=list, description="geometry: primitives and meshes, each "
                                "with a material and/or an area emitter")
    lights: list[Light] = Field(default_factory=list, description="point, spot, directional (sun), constant "
                                "and environment-map lights, each in a light group")
    light_groups: list[LightGroup] = Field(default_factory=list, description="the groups that share one "
                                           "illuminant (one transport cube each); omitted: in order of first use")
    views: list[View] = Field(min_length=1, description="cameras: one cube per view and light group")
    max_depth: int = Field(default=8, ge=1, le=64, description="longest light path (bounces)")
    # Where the scene came from, e.g. {"name": "illumix.scenegen", "version": "1", "seed": 7} or an
    # importer's {"name": "illumix.import", "format": "gltf", "file": ...}; copied into every cube's metadata.
    generator: dict[str, str | int | float] | None = Field(None, description="where the scene came from "
                                                           "(generator or importer); copied into cube metadata")

    _base: Path | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _cross_check(self) -> Scene:
        errors: list[str] = []
        for kind, items in (("shapes", self.shapes), ("lights", self.lights), ("views", self.views),
                            ("light_groups", self.light_groups)):
            seen: set[str] = set()
            for i, it in enumerate(items):
                if it.name in seen:
                    errors.append(f"{kind}[{i}] ({it.name}): name: duplicate name {it.name!r}")
                seen.add(it.name)
        declared = [g.name for g in self.light_groups]
        for i, s in enumerate(self.shapes):
            if s.material is not None and s.material not in self.materials:
                errors.append(f"shapes[{i}] ({s.name}): material: unknown material {s.material!r}; "
                              f"defined: {', '.join(self.materials) or 'none'}")
            if s.emitter is not None and declared and s.emitter.group not in declared:
                errors.append(f"shapes[{i}] ({s.name}): emitter.group: unknown light group "
                              f"{s.emitter.group!r}; declared: {', '.join(declared)}")
            if s.emitter is not None and s.emitter.portal and s.material is not None:
                errors.append(f"shapes[{i}] ({s.name}): material: a portal is not geometry; remove its material")
            if s.emitter is not None and s.material is not None and isinstance(
                    self.materials.get(s.material), Dielectric):
                errors.append(f"shapes[{i}] ({s.name}): emitter: an emitting shape cannot be dielectric")
        for i, light in enumerate(self.lights):
            if declared and light.group not in declared:
                errors.append(f"lights[{i}] ({light.name}): group: unknown light group {light.group!r}; "
                              f"declared: {', '.join(declared)}")
        skies = [light for light in self.lights if light.type in ("constant", "envmap")]
        if len(skies) > 1:
            errors.append(f"lights: at most one sky (constant or envmap) per scene, found "
                          f"{', '.join(s.name for s in skies)}")
        for name, m in self.materials.items():
            if isinstance(m, RoughConductor) and m.conductor not in CONDUCTORS:
                errors.append(f"materials.{name}: conductor: unknown conductor {m.conductor!r}; "
                              f"choose one of {', '.join(CONDUCTORS)}")
        if not self.group_names:
            errors.append("lights: the scene has no emitters; add lights or emitting shapes")
        for g in declared:
            if g not in self._used_groups():
                errors.append(f"light_groups ({g}): group {g!r} has no emitters")
        try:
            SpectralGrid(self.grid.start, self.grid.end, self.grid.step)
        except SpectralError as exc:
            errors.append(f"grid: {exc}")
        if errors:
            raise ValueError(" | ".join(errors))
        return self

    def _used_groups(self) -> list[str]:
        out: list[str] = []
        for s in self.shapes:
            if s.emitter is not None and s.emitter.group not in out:
                out.append(s.emitter.group)
        for light in self.lights:
            if light.group not in out:
                out.append(light.group)
        return out

    # -- derived ---------------------------------------------------------------------------------

    @property
    def spectral_grid(self) -> SpectralGrid:
        return SpectralGrid(self.grid.start, self.grid.end, self.grid.step)

    @property
    def group_names(self) -> list[str]:
        """Light groups in declared order (or in order of first use when none are declared)."""
        if self.light_groups:
            return [g.name for g in self.light_groups]
        return self._used_groups()

    def group(self, name: str) -> LightGroup:
        for g in self.light_groups:
            if g.name == name:
                return g
        if name in self._used_groups():
            return LightGroup(name=name)
        raise SceneError(f"scene {self.name!r}: no light group {name!r}; groups: {', '.join(self.group_names)}")

    def view(self, name: str) -> View:
        for v in self.views:
            if v.name == name:
                return v
        raise SceneError(f"scene {self.name!r}: no view {name!r}; views: {', '.join(v.name for v in self.views)}")

    def is_portal(self, item) -> bool:
        """True for a shape whose area emission is a portal (see :class:`AreaEmission`)."""
        em = getattr(item, "emitter", None)
        return em is not None and em.portal

    def emitters_of(self, group: str) -> list[Shape | Light]:
        """Shapes with area emission and lights of ``group``."""
        return [s for s in self.shapes if s.emitter is not None and s.emitter.group == group] + [
            light for light in self.lights if light.group == group]

    def resolve_path(self, p: str) -> Path:
        path = Path(p).expanduser()
        if not path.is_absolute() and self._base is not None:
            path = self._base / path
        return path

    def with_base(self, base: Path | None) -> Scene:
        self._base = base
        return self

    # -- spectra -------------------------------------------------------------------------------

    def spectrum(self, spec: SpectrumSpec, what: str, *, reflectance: bool = True) -> np.ndarray:
        """Band averages ``(n_bands,)`` float64 of a spectrum spec on the scene grid."""
        from illumix.retarget.grid import resample
        from illumix.retarget.reflectances import get_reflectances
        from illumix.retarget.tables import read_csv_table

        grid = self.spectral_grid
        extend = "constant" if reflectance else "refuse"
        if isinstance(spec, ConstantSpectrum):
            out = np.full(grid.n_bands, float(spec.value))
        elif isinstance(spec, LibrarySpectrum):
            names, r = get_reflectances(spec.library, grid)
            if spec.sample is not None:
                if spec.sample not in names:
                    raise SpectralError(f"{what}: no sample {spec.sample!r} in {spec.library!r}; "
                                        f"samples: {', '.join(names[:30])}")
                out = r[names.index(spec.sample)]
            else:
                if spec.index >= len(names):
                    raise SpectralError(f"{what}: index {spec.index} out of range; {spec.library!r} "
                                        f"has {len(names)} samples (0-based index)")
                out = r[spec.index]
        elif isinstance(spec, FileSpectrum):
            path = self.resolve_path(spec.file)
            wl, v, _ = read_csv_table(str(path), what=f"{what} file {str(path)!r}")
            if spec.column >= v.shape[1]:
                raise SpectralError(f"{what}: column {spec.column} out of range; {path} has "
                                    f"{v.shape[1]} value column(s)")
            out = resample(wl, v[:, spec.column], grid, extend=extend, what=what)
        else:
            out = resample(np.asarray(spec.wavelengths), np.asarray(spec.values), grid, extend=extend,
                           what=what)
        out = np.asarray(out, dtype=np.float64)
        if not np.all(np.isfinite(out)) or np.any(out < 0):
            raise SpectralError(f"{what}: spectrum must be finite and non-negative")
        if reflectance and np.any(out > 1.0 + 1e-6):
            raise SpectralError(f"{what}: reflectance exceeds 1 (max {out.max():.3f}); energy would "
                                "not be conserved")
        return out

    def texture_spectra(self, tex: PatternTexture, what: str) -> np.ndarray:
        """The ``K`` spectra of a pattern texture as band averages ``(K, n_bands)`` float64."""
        return np.stack([self.spectrum(s, f"{what}.spectra[{i}]") for i, s in enumerate(tex.spectra)])

    def emission(self, group: str) -> np.ndarray:
        """The emission spectrum ``Ē_g`` ``(n_bands,)`` of a light group (band averages).

        ``"flat"`` is 1 in every band. Illuminant names are looked up in :mod:`retarget.illuminants`
        (photometrically normalised, as everywhere in illumix).
        """
        g = self.group(group)
        grid = self.spectral_grid
        what = f"light_groups ({group}): emission"
        if isinstance(g.emission, str):
            if g.emission == "flat":
                return np.ones(grid.n_bands)
            if g.emission.lower().endswith(".csv"):
                return _library_spd(str(self.resolve_path(g.emission)), grid)
            return _library_spd(g.emission, grid)
        if isinstance(g.emission, FileSpectrum):
            from illumix.retarget.tables import read_csv_table

            path = self.resolve_path(g.emission.file)
            wl, v, _ = read_csv_table(str(path), what=f"{what} file {str(path)!r}")
            if g.emission.column >= v.shape[1]:
                raise SpectralError(f"{what}: column {g.emission.column} out of range")
            return spd_from_samples(wl, v[:, g.emission.column], grid, what=what)
        return spd_from_samples(np.asarray(g.emission.wavelengths), np.asarray(g.emission.values),
                                grid, what=what)

    def group_kind(self, group: str) -> str | None:
        """``daylight`` or ``artificial``: the group's declared ``kind``, else what its emitters are —
        daylight when every one is sky or sun (portals, directional lights, constant or map skies),
        artificial when every one is a lamp (other area emitters, point and spot lights); ``None``
        when they are mixed or there are none."""
        declared = self.group(group).kind
        if declared is not None:
            return declared
        sky = {isinstance(e, (DirectionalLight, ConstantSky, EnvMapSky)) or self.is_portal(e)
               for e in self.emitters_of(group)}
        return None if len(sky) != 1 else ("daylight" if sky == {True} else "artificial")

    def emission_name(self, group: str) -> str:
        e = self.group(group).emission
        return e if isinstance(e, str) else ("table" if isinstance(e, TableSpectrum) else e.file)

    # -- identity -------------------------------------------------------------------------------

    def content_hash(self) -> str:
        """sha256 over everything that changes the transport cubes except the views: geometry,
        materials, lights, groups, grid, max depth — and the bytes of every referenced file."""
        doc = self.model_dump(mode="json", exclude={"views": True, "description": True,
                                                    "light_groups": {"__all__": {"kind"}}})
        # the format's version is not content: pinned to 1 (what every hash held before version 2)
        # so that cubes rendered before the format changed keep their hash (scene.migrate)
        doc["schema_version"] = 1
        _drop_added_defaults(doc)
        files: dict[str, str] = {}
        for p in self.referenced_files():
            path = self.resolve_path(p)
            files[p] = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "missing"
        blob = json.dumps({"scene": doc, "files": files}, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()

    @cached_property
    def scene_hash(self) -> str:
        """:meth:`content_hash`, computed once."""
        return self.content_hash()

    def view_hash(self, view: str) -> str:
        """sha256 of the scene hash and one view's camera (what one cube depends on)."""
        v = self.view(view).model_dump(mode="json")
        return hashlib.sha256(json.dumps([self.scene_hash, v], sort_keys=True).encode()).hexdigest()

    def referenced_files(self) -> list[str]:
        out: list[str] = []
        for s in self.shapes:
            if isinstance(s, MeshFile):
                out.append(s.filename)
        for light in self.lights:
            if isinstance(light, EnvMapSky):
                out.append(light.filename)
        for m in self.materials.values():
            if getattr(m, "normal_map", None) is not None:
                out.append(m.normal_map.file)
            for spec in (getattr(m, "reflectance", None), getattr(m, "specular_reflectance", None)):
                if isinstance(spec, FileSpectrum):
                    out.append(spec.file)
                elif isinstance(spec, BitmapTexture):
                    out.append(spec.file)
                elif isinstance(spec, PatternTexture):
                    out.extend(s.file for s in spec.spectra if isinstance(s, FileSpectrum))
        for g in self.light_groups:
            if isinstance(g.emission, FileSpectrum):
                out.append(g.emission.file)
            elif isinstance(g.emission, str) and g.emission.lower().endswith(".csv"):
                out.append(g.emission)
        return out

    def check_resources(self) -> None:
        """Resolve every spectrum and file now, so a bad scene fails before anything renders."""
        errors: list[str] = []
        for p in self.referenced_files():
            if not self.resolve_path(p).is_file():
                errors.append(f"file {p!r} does not exist (resolved to {str(self.resolve_path(p))!r})")
        for name, m in self.materials.items():
            for field in ("reflectance", "specular_reflectance"):
                spec = getattr(m, field, None)
                if spec is not None and not isinstance(spec, BitmapTexture):
                    try:
                        if isinstance(spec, PatternTexture):
                            self.texture_spectra(spec, f"materials.{name}.{field}")
                        else:
                            self.spectrum(spec, f"materials.{name}.{field}")
                    except (SpectralError, OSError) as exc:
                        errors.append(str(exc))
        for g in self.group_names:
            try:
                e = self.emission(g)
                if not np.any(e > 0):
                    errors.append(f"light_groups ({g}): emission is zero in every band")
            except (SpectralError, OSError) as exc:
                errors.append(str(exc))
        if errors:
            raise SceneError(" | ".join(errors))
